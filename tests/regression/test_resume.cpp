// Output formats through `mpm run`, resume bit for bit, and a clean stop on SIGINT.
#include <catch2/catch.hpp>

#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <fstream>
#include <iterator>
#include <thread>

#include <hdf5.h>
#include <yaml-cpp/yaml.h>

#include "engine/io/ply.h"
#include "engine/io/output.h"
#include "support/helpers.h"

using namespace mpm;

namespace {

/// A small scene with an elastic and a plastic object (so material state is checkpointed).
std::filesystem::path small_scene(const std::filesystem::path& dir) {
  const std::string cube = test::cube_mesh();
  std::ofstream(dir / "scene.yaml") << "simulation: {frames: 4, frame_dt: 0.02, cfl: 0.5, dt: 2.0e-3}\n"
                                       "grid: {max: [1, 1, 1], dims: 24}\n"
                                       "objects:\n"
                                       "  - {name: jelly, mesh: " + cube + ", scale: 0.25, offset: [0.3, 0.3, 0.5],\n"
                                       "     velocity: [1, -2, 0], density: 500, material: corotated, E: 2.0e4, nu: 0.3}\n"
                                       "  - {name: snow, mesh: " + cube + ", scale: 0.25, offset: [0.7, 0.3, 0.5],\n"
                                       "     velocity: [-1, -2, 0], density: 400, material: snow, E: 1.0e4, nu: 0.2}\n"
                                       "walls:\n"
                                       "  - plane: {point: [0, 0.15, 0], normal: [0, 1, 0]}\n"
                                       "    boundary: sticky\n";
  return dir / "scene.yaml";
}

/// Runs `mpm ARGS` and returns its exit code; its error output goes to `stderr_file` if given.
int run_mpm(const std::string& args, const std::string& stderr_file = "/dev/null") {
  const int status = std::system(
      (std::string(MPM_BINARY) + " " + args + " > /dev/null 2> " + stderr_file).c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

/// The `frame` attribute of a checkpoint: the frame a resumed run continues from.
int checkpoint_frame(const std::string& file) {
  const hid_t f = H5Fopen(file.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  REQUIRE(f >= 0);
  const hid_t attr = H5Aopen(f, "frame", H5P_DEFAULT);
  int frame = -1;
  if (attr >= 0) H5Aread(attr, H5T_NATIVE_INT, &frame);
  if (attr >= 0) H5Aclose(attr);
  H5Fclose(f);
  return frame;
}

/// The whole text of `file`.
std::string read_text(const std::filesystem::path& file) {
  std::ifstream in(file);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

}  // namespace

TEST_CASE("every output format is written for every frame", "[regression]") {
  const auto dir = test::temp_dir("formats");
  const auto scene = small_scene(dir);
  REQUIRE(run_mpm("run " + scene.string() + " --frames 2 --quiet --format hdf5,bgeo,ply,png --out " +
              (dir / "out").string()) == 0);
  for (int f = 0; f <= 2; ++f) {
    char name[32];
    std::snprintf(name, sizeof name, "frame_%05d", f);
    INFO(name);
    CHECK(std::filesystem::exists(dir / "out" / (std::string(name) + ".h5")));
    CHECK(std::filesystem::exists(dir / "out" / (std::string(name) + ".bgeo")));
    CHECK(std::filesystem::exists(dir / "out" / "preview" / (std::string(name) + ".png")));
    // The PLY holds the same particles as the HDF5 frame.
    const FrameData h5 = read_frame_hdf5(dir / "out" / (std::string(name) + ".h5"));
    const PlyPoints ply = read_ply(dir / "out" / (std::string(name) + ".ply"));
    CHECK(ply.position == h5.position);
    CHECK(ply.object_id == h5.object_id);
  }
  const std::string xmf = read_text(dir / "out" / "frames.xmf");
  CHECK(xmf.find("frame_00002.h5:/position") != std::string::npos);
}

TEST_CASE("a resumed run equals an uninterrupted one bit for bit", "[regression]") {
  const auto dir = test::temp_dir("resume");
  const auto scene = small_scene(dir);
  // With contact at the particles the checkpoint also carries the contact impulses each
  // solve starts from (ContactMemory).
  for (const std::string contact : {"particles", "nodes"}) {
    INFO("contact: " << contact);
    const std::string a = (dir / ("a_" + contact)).string(), b = (dir / ("b_" + contact)).string();
    const std::string run = "run " + scene.string() + " --set simulation.contact=" + contact;
    REQUIRE(run_mpm(run + " --frames 4 --quiet --out " + a) == 0);
    REQUIRE(run_mpm(run + " --frames 2 --quiet --out " + b) == 0);
    REQUIRE(run_mpm(run + " --frames 4 --quiet --resume " + b) == 0);
    for (int f = 3; f <= 4; ++f) {
      INFO("frame " << f);
      const FrameData x = read_frame_hdf5(frame_path(a, f)), y = read_frame_hdf5(frame_path(b, f));
      CHECK(x.position == y.position);
      CHECK(x.velocity == y.velocity);
      CHECK(x.J == y.J);
      CHECK(x.time == y.time);
    }
  }
  const std::string a = (dir / "a_nodes").string(), b = (dir / "b_nodes").string();
  const YAML::Node ra = YAML::LoadFile(a + "/report.yaml"), rb = YAML::LoadFile(b + "/report.yaml");
  CHECK(ra["substeps"].as<std::size_t>() == rb["substeps"].as<std::size_t>());
  CHECK(rb["frames"].as<int>() == 4);
  CHECK(rb["checkpoint_frame"].as<int>() == 4);
  // Without --force a finished folder is not overwritten.
  CHECK(run_mpm("run " + scene.string() + " --frames 1 --quiet --out " + a) == 2);
  CHECK(run_mpm("run " + scene.string() + " --frames 1 --quiet --force --out " + a) == 0);
  CHECK_FALSE(std::filesystem::exists(frame_path(a, 2)));
}

TEST_CASE("the checkpoint is written on its wall-clock interval and always at the end",
          "[regression]") {
  const auto dir = test::temp_dir("checkpoint_interval");
  const auto scene = small_scene(dir);
  const std::string a = (dir / "a").string(), b = (dir / "b").string();
  // An interval longer than the run: only the end's checkpoint, of the last frame.
  REQUIRE(run_mpm("run " + scene.string() + " --frames 3 --quiet --out " + a +
                  " --set output.checkpoint_interval=1000") == 0);
  const YAML::Node ra = YAML::LoadFile(a + "/report.yaml");
  CHECK(ra["checkpoints"].as<int>() == 1);
  CHECK(ra["checkpoint_frame"].as<int>() == 3);
  CHECK(checkpoint_frame(a + "/checkpoint.h5") == 3);
  // Interval 0: after every frame, frame 0 included, as before the interval existed.
  REQUIRE(run_mpm("run " + scene.string() + " --frames 3 --quiet --out " + b +
                  " --set output.checkpoint_interval=0") == 0);
  const YAML::Node rb = YAML::LoadFile(b + "/report.yaml");
  CHECK(rb["checkpoints"].as<int>() == 4);
  CHECK(checkpoint_frame(b + "/checkpoint.h5") == 3);
  // Off: none at all.
  REQUIRE(run_mpm("run " + scene.string() + " --frames 1 --quiet --force --out " + a +
                  " --set output.checkpoint=false") == 0);
  CHECK(YAML::LoadFile(a + "/report.yaml")["checkpoints"].as<int>() == 0);
  CHECK(run_mpm("run " + scene.string() + " --frames 1 --quiet --force --out " + a +
                " --set output.checkpoint_interval=-1") == 2);
}

TEST_CASE("a checkpoint of the other storage precision is refused, not resumed",
          "[regression]") {
  const auto dir = test::temp_dir("resume_precision");
  const auto scene = small_scene(dir);
  const std::string b = (dir / "b").string();
  REQUIRE(run_mpm("run " + scene.string() + " --frames 2 --quiet --out " + b) == 0);
  {  // Mark the checkpoint as written by the other build.
    const hid_t f = H5Fopen((b + "/checkpoint.h5").c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
    REQUIRE(f >= 0);
    const hid_t attr = H5Aopen(f, "stored_real_bytes", H5P_DEFAULT);
    REQUIRE(attr >= 0);
    const int other = sizeof(StoredReal) == 4 ? 8 : 4;
    CHECK(H5Awrite(attr, H5T_NATIVE_INT, &other) >= 0);
    H5Aclose(attr);
    H5Fclose(f);
  }
  const std::string log = (dir / "log.txt").string();
  CHECK(run_mpm("run " + scene.string() + " --frames 4 --quiet --resume " + b, log) == 2);
  const std::string text = read_text(log);
  INFO(text);
  CHECK(text.find("--resume") != std::string::npos);
  CHECK(text.find("MPM_DOUBLE_PARTICLES") != std::string::npos);
  CHECK_FALSE(std::filesystem::exists(frame_path(b, 3)));
}

TEST_CASE(
    "SIGINT stops a run at a frame end with its checkpoint; the resumed run ends as an "
    "uninterrupted one",
    "[regression]") {
  const auto dir = test::temp_dir("interrupt");
  const auto scene = small_scene(dir);
  const std::string out = (dir / "out").string();
  const pid_t pid = fork();
  REQUIRE(pid >= 0);
  if (pid == 0) {
    const std::string log = (dir / "log.txt").string();
    freopen(log.c_str(), "w", stdout);
    freopen(log.c_str(), "a", stderr);
    execl(MPM_BINARY, MPM_BINARY, "run", scene.c_str(), "--frames", "100000", "--out",
          out.c_str(), "--quiet", static_cast<char*>(nullptr));
    _exit(127);
  }
  // Wait until a few frames exist, then interrupt.
  for (int i = 0; i < 600 && !std::filesystem::exists(frame_path(out, 3)); ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  REQUIRE(std::filesystem::exists(frame_path(out, 3)));
  kill(pid, SIGINT);
  int status = 0;
  waitpid(pid, &status, 0);
  REQUIRE(WIFEXITED(status));
  CHECK(WEXITSTATUS(status) == 1);
  const YAML::Node report = YAML::LoadFile(out + "/report.yaml");
  CHECK(report["status"].as<std::string>() == "interrupted");
  const int frames = report["frames"].as<int>();
  CHECK(frames >= 3);
  for (int f = 0; f <= frames; ++f) CHECK_NOTHROW(read_frame_hdf5(frame_path(out, f)));
  CHECK_FALSE(std::filesystem::exists(frame_path(out, frames + 1)));
  // The stop wrote the checkpoint of its last frame (the default interval, 15 s, is longer
  // than the run).
  CHECK(report["checkpoint_frame"].as<int>() == frames);
  CHECK(checkpoint_frame(out + "/checkpoint.h5") == frames);
  // The interrupted run resumes, and ends bit for bit where an uninterrupted one does.
  const int last = frames + 2;
  REQUIRE(run_mpm("run " + scene.string() + " --frames " + std::to_string(last) +
                  " --quiet --resume " + out) == 0);
  const std::string whole = (dir / "whole").string();
  REQUIRE(run_mpm("run " + scene.string() + " --frames " + std::to_string(last) +
                  " --quiet --out " + whole) == 0);
  const FrameData x = read_frame_hdf5(frame_path(whole, last)),
                  y = read_frame_hdf5(frame_path(out, last));
  CHECK(x.position == y.position);
  CHECK(x.velocity == y.velocity);
  CHECK(x.J == y.J);
  CHECK(x.time == y.time);
}

TEST_CASE("a run made unstable on purpose stops with a diagnosis and keeps its frames",
          "[regression]") {
  const auto dir = test::temp_dir("unstable");
  const std::string out = (dir / "out").string();
  // dt = 0.02 s is about seven times the CFL bound of jello_cube (0.0028 s): it must be caught.
  CHECK(run_mpm("run " + (test::source_dir() / "scenes/jello_cube.yaml").string() +
                " --set simulation.dt=0.02 --frames 20 --quiet --out " + out) == 1);
  const YAML::Node report = YAML::LoadFile(out + "/report.yaml");
  CHECK(report["status"].as<std::string>() == "unstable");
  const YAML::Node why = report["instability"];
  REQUIRE(why.IsMap());
  CHECK(why["object"].as<std::string>() == "jello");
  CHECK(why["cause"].as<std::string>().find("cells per substep") != std::string::npos);
  const double suggested = why["suggested_dt"].as<double>();
  CHECK(suggested > 0);
  CHECK(suggested < 0.0028);
  const int frames = report["frames"].as<int>();
  CHECK(why["frame"].as<int>() == frames + 1);  // stopped while computing the next frame
  CHECK(why["substep"].as<std::size_t>() == report["substeps"].as<std::size_t>());
  for (int f = 0; f <= frames; ++f) CHECK_NOTHROW(read_frame_hdf5(frame_path(out, f)));
  CHECK_FALSE(std::filesystem::exists(frame_path(out, frames + 1)));
}

TEST_CASE("mpm preview makes a movie where ffmpeg exists, and says why not elsewhere",
          "[regression]") {
  const auto dir = test::temp_dir("preview_movie");
  const auto scene = small_scene(dir);
  const std::string out = (dir / "out").string();
  REQUIRE(run_mpm("run " + scene.string() + " --frames 2 --quiet --format png --out " + out) == 0);
  const bool have_ffmpeg = std::system("command -v ffmpeg > /dev/null 2>&1") == 0;
  const int code = run_mpm("preview " + out);
  if (have_ffmpeg) {
    CHECK(code == 0);
    CHECK(std::filesystem::file_size(dir / "out" / "preview.mp4") > 1000);
  } else {
    CHECK(code == 1);  // the PNG frames are there; the movie needs ffmpeg
    CHECK_FALSE(std::filesystem::exists(dir / "out" / "preview.mp4"));
  }
  CHECK(run_mpm("preview " + (dir / "nowhere").string()) == 2);
}
