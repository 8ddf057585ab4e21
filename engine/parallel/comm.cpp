#include "engine/parallel/comm.h"

#include <mpi.h>

#include <chrono>
#include <cstdlib>
#include <stdexcept>
#include <utility>

namespace mpm::parallel {

namespace {

bool initialised() {
  int init = 0, done = 0;
  MPI_Initialized(&init);
  MPI_Finalized(&done);
  return init && !done;
}

/// Times one MPI call into comm_stats().
template <class Fn>
void timed(Fn&& fn) {
  const auto t0 = std::chrono::steady_clock::now();
  fn();
  comm_stats().seconds +=
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  ++comm_stats().messages;
}

}  // namespace

Session::Session(int& argc, char**& argv) {
  // Only under a launcher (mpirun, srun): a plain `mpm run` stays free of MPI start-up.
  const bool launched =
      std::getenv("OMPI_COMM_WORLD_SIZE") || std::getenv("PMI_SIZE") || std::getenv("PMIX_RANK");
  if (!launched || initialised()) return;
  int provided = 0;
  MPI_Init_thread(&argc, &argv, MPI_THREAD_FUNNELED, &provided);
  owns_ = true;
}

Session::~Session() {
  if (owns_ && initialised()) MPI_Finalize();
}

int rank() {
  if (!initialised()) return 0;
  int r = 0;
  MPI_Comm_rank(MPI_COMM_WORLD, &r);
  return r;
}

int ranks() {
  if (!initialised()) return 1;
  int n = 1;
  MPI_Comm_size(MPI_COMM_WORLD, &n);
  return n;
}

void abort_all(int code) {
  if (initialised()) MPI_Abort(MPI_COMM_WORLD, code);
  std::exit(code);
}

CommStats& comm_stats() {
  static CommStats stats;
  return stats;
}

namespace {

double reduce(double x, MPI_Op op) {
  if (ranks() == 1) return x;
  double out = x;
  timed([&] { MPI_Allreduce(&x, &out, 1, MPI_DOUBLE, op, MPI_COMM_WORLD); });
  return out;
}

}  // namespace

double min_all(double x) {
  return reduce(x, MPI_MIN);
}
double max_all(double x) {
  return reduce(x, MPI_MAX);
}
double sum_all(double x) {
  return reduce(x, MPI_SUM);
}

std::uint64_t sum_all(std::uint64_t x) {
  if (ranks() == 1) return x;
  std::uint64_t out = x;
  timed([&] { MPI_Allreduce(&x, &out, 1, MPI_UINT64_T, MPI_SUM, MPI_COMM_WORLD); });
  return out;
}

std::vector<std::uint64_t> sum_all(std::vector<std::uint64_t> x) {
  if (ranks() == 1) return x;
  std::vector<std::uint64_t> out(x.size());
  timed([&] {
    MPI_Allreduce(x.data(), out.data(), static_cast<int>(x.size()), MPI_UINT64_T, MPI_SUM,
                  MPI_COMM_WORLD);
  });
  return out;
}

bool any_all(bool x) {
  if (ranks() == 1) return x;
  int in = x ? 1 : 0, out = 0;
  timed([&] { MPI_Allreduce(&in, &out, 1, MPI_INT, MPI_MAX, MPI_COMM_WORLD); });
  return out != 0;
}

void broadcast(int& x) {
  if (ranks() == 1) return;
  timed([&] { MPI_Bcast(&x, 1, MPI_INT, 0, MPI_COMM_WORLD); });
}

void broadcast(std::string& x) {
  if (ranks() == 1) return;
  int n = static_cast<int>(x.size());
  broadcast(n);
  x.resize(n);
  timed([&] { MPI_Bcast(x.data(), n, MPI_CHAR, 0, MPI_COMM_WORLD); });
}

void broadcast(std::vector<int>& x) {
  if (ranks() == 1) return;
  int n = static_cast<int>(x.size());
  broadcast(n);
  x.resize(n);
  timed([&] { MPI_Bcast(x.data(), n, MPI_INT, 0, MPI_COMM_WORLD); });
}

std::string first_nonempty(const std::string& local) {
  const int n = ranks();
  if (n == 1) return local;
  int mine = local.empty() ? n : rank(), root = n;
  timed([&] { MPI_Allreduce(&mine, &root, 1, MPI_INT, MPI_MIN, MPI_COMM_WORLD); });
  if (root == n) return {};
  std::string out = local;
  int size = static_cast<int>(out.size());
  timed([&] { MPI_Bcast(&size, 1, MPI_INT, root, MPI_COMM_WORLD); });
  out.resize(size);
  timed([&] { MPI_Bcast(out.data(), size, MPI_CHAR, root, MPI_COMM_WORLD); });
  return out;
}

std::vector<double> all_gather(double x) {
  std::vector<double> out(ranks(), x);
  if (ranks() > 1)
    timed([&] { MPI_Allgather(&x, 1, MPI_DOUBLE, out.data(), 1, MPI_DOUBLE, MPI_COMM_WORLD); });
  return out;
}

std::vector<double> all_gather(const std::vector<double>& x) {
  if (ranks() == 1) return x;
  std::vector<double> out(x.size() * ranks());
  const int n = static_cast<int>(x.size());
  timed([&] { MPI_Allgather(x.data(), n, MPI_DOUBLE, out.data(), n, MPI_DOUBLE, MPI_COMM_WORLD); });
  comm_stats().bytes += x.size() * sizeof(double);
  return out;
}

double sum_in_rank_order(double x) {
  if (ranks() == 1) return x;
  double total = 0;
  for (double part : all_gather(x)) total += part;
  return total;
}

std::vector<std::uint64_t> all_gather(std::uint64_t x) {
  std::vector<std::uint64_t> out(ranks(), x);
  if (ranks() > 1)
    timed([&] { MPI_Allgather(&x, 1, MPI_UINT64_T, out.data(), 1, MPI_UINT64_T, MPI_COMM_WORLD); });
  return out;
}

std::vector<char> send_receive(const std::vector<char>& send, int to, int from) {
  const int dest = to < 0 ? MPI_PROC_NULL : to, source = from < 0 ? MPI_PROC_NULL : from;
  std::uint64_t n_send = send.size(), n_recv = 0;
  timed([&] {
    MPI_Sendrecv(&n_send, 1, MPI_UINT64_T, dest, 0, &n_recv, 1, MPI_UINT64_T, source, 0,
                 MPI_COMM_WORLD, MPI_STATUS_IGNORE);
  });
  std::vector<char> recv(source == MPI_PROC_NULL ? 0 : n_recv);
  timed([&] {
    MPI_Sendrecv(send.data(), static_cast<int>(n_send), MPI_BYTE, dest, 1, recv.data(),
                 static_cast<int>(recv.size()), MPI_BYTE, source, 1, MPI_COMM_WORLD,
                 MPI_STATUS_IGNORE);
  });
  if (dest != MPI_PROC_NULL) comm_stats().bytes += n_send + sizeof n_send;
  return recv;
}

std::vector<std::vector<char>> all_to_all(const std::vector<std::vector<char>>& send) {
  const int n = ranks();
  if (n == 1) return send;
  std::vector<int> send_counts(n), recv_counts(n), send_offsets(n), recv_offsets(n);
  std::vector<char> flat;
  for (int r = 0; r < n; ++r) {
    send_counts[r] = static_cast<int>(send[r].size());
    send_offsets[r] = static_cast<int>(flat.size());
    flat.insert(flat.end(), send[r].begin(), send[r].end());
    if (r != rank()) comm_stats().bytes += send[r].size();
  }
  timed([&] {
    MPI_Alltoall(send_counts.data(), 1, MPI_INT, recv_counts.data(), 1, MPI_INT, MPI_COMM_WORLD);
  });
  int total = 0;
  for (int r = 0; r < n; ++r) recv_offsets[r] = total, total += recv_counts[r];
  std::vector<char> recv(total);
  timed([&] {
    MPI_Alltoallv(flat.data(), send_counts.data(), send_offsets.data(), MPI_BYTE, recv.data(),
                  recv_counts.data(), recv_offsets.data(), MPI_BYTE, MPI_COMM_WORLD);
  });
  std::vector<std::vector<char>> out(n);
  for (int r = 0; r < n; ++r)
    out[r].assign(recv.begin() + recv_offsets[r], recv.begin() + recv_offsets[r] + recv_counts[r]);
  return out;
}

namespace {

/// MPM_TEST_FAIL_RANK and MPM_TEST_FAIL_SUBSTEP, or -1 where unset.
std::pair<long, long> test_failure() {
  static const std::pair<long, long> at = [] {
    const char* r = std::getenv("MPM_TEST_FAIL_RANK");
    const char* s = std::getenv("MPM_TEST_FAIL_SUBSTEP");
    if (!r || !s) return std::pair<long, long>{-1, -1};
    return std::pair<long, long>{std::strtol(r, nullptr, 10), std::strtol(s, nullptr, 10)};
  }();
  return at;
}

}  // namespace

bool test_failure_requested() {
  return test_failure().first >= 0;
}

void test_failure_point(std::size_t substeps) {
  const auto [r, s] = test_failure();
  if (r == rank() && static_cast<long>(substeps) == s)
    throw std::runtime_error("test failure at substep " + std::to_string(substeps) +
                             " (MPM_TEST_FAIL_RANK, MPM_TEST_FAIL_SUBSTEP)");
}

}  // namespace mpm::parallel
