#include "engine/step/simulation.h"

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <span>
#include <utility>

#include "engine/core/reduce.h"
#include "engine/scene/mesh.h"
#include "engine/scene/sampling.h"
#include "engine/step/reorder.h"
#include "engine/step/simd/stress_simd.h"
#include "engine/step/simd/transfer_simd.h"

namespace mpm {

namespace {

template <class T>
std::span<T> slice(std::vector<T>& v, const MaterialRange& r) {
  return std::span<T>(v).subspan(r.first, r.count);
}

template <class T>
std::span<const T> slice(const std::vector<T>& v, const MaterialRange& r) {
  return std::span<const T>(v).subspan(r.first, r.count);
}

}  // namespace

Simulation::Simulation(const SceneDesc& scene)
    : scene_(scene), grid_(scene.grid, scene.simulation.transfer == Transfer::flip) {}

namespace {

/// Throws SceneError if `bytes` cannot fit in this machine's memory.
void check_memory(double bytes, const FileLoc& loc, const std::string& key, const std::string& what) {
  const double have = static_cast<double>(sysconf(_SC_PHYS_PAGES)) * sysconf(_SC_PAGE_SIZE);
  if (bytes > 0.8 * have) {
    char buf[160];
    std::snprintf(buf, sizeof buf, " needs %.3g GB of memory; this machine has %.3g GB", bytes / 1e9,
                  have / 1e9);
    throw SceneError(loc, key, what + buf);
  }
}

}  // namespace

std::unique_ptr<Simulation> Simulation::create(const SceneDesc& scene,
                                               const MaterialRegistry& registry) {
  // The grid's node storage follows the particles. What covers the domain: its page table (one
  // int per 4^3-node block), and at worst the sort's count per cell of the particles' box.
  const Vec3 blocks = (scene.grid.dims + Vec3i::Constant(Grid::kBlockEdge))
                          .cast<Real>() / Grid::kBlockEdge;
  const double cells = scene.grid.dims.cast<double>().prod();
  const std::string grid_name = "the grid of " + std::to_string(scene.grid.dims.x()) + " x " +
                                std::to_string(scene.grid.dims.y()) + " x " +
                                std::to_string(scene.grid.dims.z()) + " cells";
  check_memory((blocks.prod() + cells) * sizeof(std::int32_t), scene.grid.loc, "grid.dims",
               grid_name);
  if (cells >= 4294967296.0)  // the sort's cell keys are 32-bit
    throw SceneError(scene.grid.loc, "grid.dims",
                     grid_name + " has more than 2^32 cells, the most the sort can key");
  std::unique_ptr<Simulation> sim(new Simulation(scene));
  Particles& P = sim->particles_;
  const Vec3 h = scene.grid.spacing();
  const Real cell_volume = h.prod();
  const Vec3 interior_lo = scene.grid.origin + scene.grid.buffer * h;
  const Vec3 interior_hi = scene.grid.max - scene.grid.buffer * h;

  for (std::size_t o = 0; o < scene.objects.size(); ++o) {
    const ObjectDesc& od = scene.objects[o];
    const std::string key = "objects[" + std::to_string(o) + "]";
    TriangleMesh mesh;
    try {
      mesh = load_mesh(od.mesh);
    } catch (const MeshError& e) {
      throw SceneError(od.mesh_loc, key + ".mesh", e.what());
    }
    if (const std::string why = closedness_problem(mesh); !why.empty())
      throw SceneError(od.mesh_loc, key + ".mesh", "'" + od.mesh.string() + "': " + why);
    transform_mesh(mesh, od.scale, od.rotation_deg, od.offset);
    Eigen::AlignedBox<Real, 3> box;
    for (const Vec3& v : mesh.vertices) box.extend(v);
    // Where the object and the interior lie, for errors about one outside the other.
    const auto corners = [](const Vec3& a, const Vec3& b) {
      char buf[160];
      std::snprintf(buf, sizeof buf, "[%g, %g, %g] to [%g, %g, %g]", a.x(), a.y(), a.z(), b.x(),
                    b.y(), b.z());
      return std::string(buf);
    };
    const auto outside = [&](const std::string& how) {
      return SceneError(od.placement_loc, key + ".offset",
                        "object '" + od.name + "' lies " + how +
                            " the grid interior (the grid minus its buffer of " +
                            std::to_string(scene.grid.buffer) + " cells): the object spans " +
                            corners(box.min(), box.max()) + ", the interior " +
                            corners(interior_lo, interior_hi));
    };
    if ((box.min().array() > interior_hi.array()).any() ||
        (box.max().array() < interior_lo.array()).any())
      throw outside("outside");
    {  // Refuse before sampling an object whose particles could never fit in memory.
      const Vec3 cells = box.sizes().cwiseQuotient(h) + Vec3::Ones();
      check_memory(cells.prod() * od.particles_per_cell * 400.0, od.loc, key,
                   "object '" + od.name + "' at " + std::to_string(od.particles_per_cell) +
                       " particles per cell");
    }
    std::vector<Vec3> points =
        sample_inside(mesh, scene.grid, od.particles_per_cell,
                      od.sampling == Sampling::regular, scene.simulation.seed, o);
    for (const Vec3& x : points)
      if ((x.array() < interior_lo.array()).any() || (x.array() > interior_hi.array()).any())
        throw outside("partly outside");
    if (points.empty())
      throw SceneError(od.loc, key, "object '" + od.name + "' samples zero particles: it spans " +
                                        corners(box.min(), box.max()) +
                                        ", less than the particle spacing");

    const std::size_t n = points.size();
    const Real v0 = cell_volume / od.particles_per_cell;
    const Real total_mass = od.mass ? *od.mass : *od.density * v0 * n;
    const Real density = total_mass / (v0 * n);
    ObjectInfo info{od.name, od.material, P.size(), n, total_mass, density};

    // v = v0 + L (x - centroid), L = velocity_gradient + skew(angular_velocity).
    Vec3 centroid = Vec3::Zero();
    for (const Vec3& x : points) centroid += x / static_cast<Real>(n);
    const Vec3& w = od.angular_velocity;
    Mat3 L = od.velocity_gradient;
    L += (Mat3() << 0, -w.z(), w.y(), w.z(), 0, -w.x(), -w.y(), w.x(), 0).finished();
    // Arrays grown to exact sizes, and the samples freed before the matrices are allocated:
    // the peak memory of creation stays below that of the step.
    P.x.insert(P.x.end(), points.begin(), points.end());
    std::vector<Vec3>().swap(points);
    P.v.reserve(P.v.size() + n);
    for (std::size_t q = info.first; q < info.first + n; ++q)
      P.v.push_back(od.velocity + L * (P.x[q] - centroid));
    P.id.reserve(P.id.size() + n);
    if (scene.simulation.transfer == Transfer::apic || scene.simulation.transfer == Transfer::mls)
      P.C.insert(P.C.end(), n, to_stored(L));
    P.F.insert(P.F.end(), n, StoredMat3::Identity());
    P.object.insert(P.object.end(), n, static_cast<std::uint32_t>(o));
    for (std::size_t q = info.first; q < info.first + n; ++q)
      P.id.push_back(static_cast<std::uint32_t>(q));
    P.object_mass.push_back(total_mass / n);
    P.object_volume0.push_back(v0);

    const MaterialInfo* mat = registry.find(od.material);
    if (!mat) throw SceneError(od.loc, key + ".material", "unknown material '" + od.material + "'");
    // A factory may reject a combination of parameters by throwing (docs/materials.md).
    std::unique_ptr<MaterialGroup> group;
    try {
      group = mat->create(
          od.params, GroupInfo{density, n, {P.x.data() + info.first, n}, scene.simulation.seed});
    } catch (const std::exception& e) {
      throw SceneError(od.loc, key, "material '" + od.material + "' rejects the parameters of " +
                                        "object '" + od.name + "': " + e.what());
    }
    if (!group)
      throw SceneError(od.loc, key, "material '" + od.material + "' built no material group");
    // Contact at the particles: the surface particles of an elastic body take their depth
    // below its surface as their radius (engine/step/contact.h).
    if (scene.simulation.contact == Contact::particles && !group->has_plasticity()) {
      const Real spacing = std::cbrt(v0);
      const std::vector<Real> depth = depth_below_surface(mesh, {P.x.data() + info.first, n},
                                                          spacing / 4, kRestDepthCap * spacing / 2);
      sim->contact_.rest_depth.resize(P.size(), -1);
      std::copy(depth.begin(), depth.end(), sim->contact_.rest_depth.begin() + info.first);
    }
    sim->state_stride_.push_back(group->state().size() / n);
    sim->group_factories_.push_back(
        [create = mat->create, params = od.params, density](std::size_t count) {
          return create(params, GroupInfo{density, count});
        });
    sim->materials_.push_back({info.first, n, std::move(group)});
    sim->objects_.push_back(info);
  }
  if (!sim->contact_.rest_depth.empty()) sim->contact_.rest_depth.resize(P.size(), -1);
  sim->contact_.mls_quadrature = scene.simulation.transfer == Transfer::mls;
  sim->walls_ = build_wall_planes(scene.walls);
  // Mesh level sets get voxels of half the cell size.
  sim->colliders_ = build_colliders(scene.walls, sim->grid_.h.minCoeff() / 2);
  sim->build_stages();
  return sim;
}

void Simulation::build_stages() {
  const SimulationDesc& s = scene_.simulation;
  stages_.clear();
  // With more than one rank a stage's exception is kept in the domain and the rank's later
  // compute stages are skipped, while its exchanges still run (the other ranks wait in them):
  // run_frames then stops every rank at the end of the substep (docs/distributed.md).
  auto add = [&](std::string name, std::function<void(Real)> fn) {
    if (domain_)
      fn = [this, name, fn = std::move(fn)](Real dt) {
        if (!domain_->failure().empty()) return;
        try {
          fn(dt);
        } catch (const std::exception& e) {
          domain_->set_failure("stage " + name + ": " + e.what());
        }
      };
    stages_.push_back({std::move(name), std::move(fn), 0.0});
  };
  auto exchange = [&](std::string name, std::function<void(Real)> fn) {
    stages_.push_back({std::move(name), std::move(fn), 0.0});
  };
  add("sort", [this](Real) { sort_particles(particles_, scene_.simulation.kernel, grid_, order_); });
  // With more than one rank: the previous rank's ghost blocks get storage here too.
  if (domain_) exchange("halo_blocks", [this](Real) { domain_->share_ghost_blocks(grid_); });
  // The stress of each group (object), chosen here once per group: with simulation.simd, a
  // group whose model has an engine SIMD kernel gets it folded into the SIMD scatter (no
  // stress array, no pass), or, where the scatter is scalar (FLIP), run as its own SIMD pass;
  // any other group runs its compute_stress into Particles::stress.
  const bool simd_transfers = s.simd && simd::supports(s.transfer, s.kernel, grid_);
  std::vector<BatchModel> batch, fold;
  bool stored = false;
  for (const auto& m : materials_) {
    const BatchModel b = m.material->batch_model();
    const bool lanes = s.simd && simd::supports_stress(b);
    fold.push_back(lanes && simd_transfers ? b : BatchModel{});
    batch.push_back(lanes && !simd_transfers ? b : BatchModel{});
    stored |= !(lanes && simd_transfers);
  }
  if (!std::any_of(fold.begin(), fold.end(),
                   [](const BatchModel& b) { return b.kind != BatchModel::Kind::none; }))
    fold.clear();
  // Only what the scene calls for is stored.
  stores_stress_ = stored;
  particles_.stress.assign(stored ? particles_.size() : 0, StoredMat3::Zero());
  particles_.stress.shrink_to_fit();
  if (stored)
    add("compute_stress", [this, batch, fold](Real) {
      for (std::size_t g = 0; g < materials_.size(); ++g) {
        if (g < fold.size() && fold[g].kind != BatchModel::Kind::none) continue;
        const auto& m = materials_[g];
        if (m.count == 0) continue;  // an object with no particles on this rank
        const auto F = slice(std::as_const(particles_.F), m);
        const Real v0 = particles_.volume0(m.first);
        if (batch[g].kind != BatchModel::Kind::none)
          simd::stress(batch[g], F, v0, slice(particles_.stress, m));
        else
          m.material->compute_stress(F, v0, slice(particles_.stress, m));
      }
    });
  add("particles_to_grid",
      [this, fold](Real dt) {
        const SimulationDesc& sd = scene_.simulation;
        particles_to_grid(particles_, order_, sd.transfer, sd.kernel, dt, grid_,
                          sd.simd ? TransferPath::simd : TransferPath::scalar, fold);
      });
  // Between the transfers, where v and C are dead unless FLIP blends the old v.
  if (s.reorder_every > 0)
    add("reorder", [this](Real) {
      if (substeps_ % scene_.simulation.reorder_every != 0) return;
      std::vector<ReorderRange> ranges;
      for (auto& m : materials_)  // an object with no particles here (other ranks) has none
        if (m.count > 0) ranges.push_back({m.first, m.count, m.material->state()});
      reorder_particles(ranges, scene_.simulation.transfer == Transfer::flip, order_,
                        particles_);
    });
  if (domain_) exchange("halo_sum", [this](Real) { domain_->add_ghost_sums(grid_); });
  add("grid_update", [this](Real) { grid_update(grid_); });
  // PIC and APIC scatter the stress force as an impulse (see particles_to_grid).
  if (s.transfer == Transfer::flip)
    add("stress_forces", [this](Real dt) { apply_stress_forces(dt, grid_); });
  if (s.gravity.squaredNorm() > 0)
    add("gravity", [this](Real dt) { apply_gravity(dt, scene_.simulation.gravity, grid_); });
  if (s.damping > 0)
    add("damping", [this](Real dt) { apply_damping(dt, scene_.simulation.damping, grid_); });
  if (s.contact == Contact::nodes) {
    // Walls act on the grid velocities of the end of the substep: place them at time + dt.
    if (!walls_.empty())
      add("walls", [this](Real dt) { wall_work_ += apply_walls(walls_, time_ + dt, grid_); });
    if (!colliders_.empty())
      add("colliders",
          [this](Real dt) { wall_work_ += apply_colliders(colliders_, time_ + dt, grid_); });
    add("domain_boundary", [this](Real) { apply_domain_boundary(grid_); });
    if (domain_)
      exchange("halo_velocity", [this](Real) { domain_->return_ghost_velocities(grid_); });
  } else {
    // With more than one rank the ghosts take their owners' mass and velocity first: contact
    // reads the nodes around every contact point.
    if (domain_)
      exchange("halo_velocity", [this](Real) { domain_->return_ghost_velocities(grid_); });
    // Walls and colliders act where the particles touch them (engine/step/contact.h).
    if (!walls_.empty() || !colliders_.empty())
      add("contact", [this](Real dt) {
        const Kernel kernel = scene_.simulation.kernel;
        if (!domain_) {
          wall_work_ += apply_contact(walls_, colliders_, ContactSettings{}, kernel, time_, dt,
                                      particles_, grid_, contact_);
          return;
        }
        find_contacts(walls_, colliders_, kernel, time_, dt, particles_, grid_, contact_);
      });
    // The solve over every rank's contacts is collective: a rank whose stages failed takes
    // part with none.
    if (domain_ && (!walls_.empty() || !colliders_.empty()))
      exchange("contact_solve", [this](Real dt) {
        if (!domain_->failure().empty()) contact_.clear();
        wall_work_ += domain_->solve_contact(ContactSettings{}, dt, contact_, grid_);
      });
    add("domain_boundary", [this](Real) { apply_domain_boundary(grid_); });
  }
  // Advection runs inside the gather: on the SIMD path each lane set is advected while its x
  // and v are in cache (the plasticity stage below reads and writes only F and its own state,
  // so the order of the two does not matter).
  add("grid_to_particles", [this](Real dt) {
    const SimulationDesc& sd = scene_.simulation;
    grid_to_particles(grid_, sd.transfer, sd.kernel, sd.flip_blend, dt, particles_,
                      sd.simd ? TransferPath::simd : TransferPath::scalar, &last_advect_);
    clamped_total_ += last_advect_.clamped;
  });
  const bool plastic = std::any_of(materials_.begin(), materials_.end(),
                                   [](const auto& m) { return m.material->has_plasticity(); });
  if (plastic)
    add("plasticity", [this](Real dt) {
      for (auto& m : materials_)
        if (m.material->has_plasticity())
          m.material->apply_plasticity_step(slice(particles_.F, m), dt);
    });
  // The run's checks see every rank's advection; particles move to their new slab's rank.
  if (domain_ && domain_->test_failure_requested())
    add("test_failure", [this](Real) { domain_->test_failure_point(substeps_ + 1); });
  if (domain_)
    exchange("migrate", [this](Real) {
      const AdvectStats local = last_advect_;
      domain_->migrate(*this);
      last_advect_ = domain_->combine(local);
    });
}

void Simulation::set_domain(std::shared_ptr<RankExchange> domain) {
  domain_ = std::move(domain);
  build_stages();
}

void Simulation::replace_particles(Particles&& p, const std::vector<std::size_t>& counts,
                                   std::vector<std::vector<Real>>&& states) {
  particles_ = std::move(p);
  ++state_;
  std::size_t first = 0;
  for (std::size_t o = 0; o < objects_.size(); ++o) {
    objects_[o].first = first;
    objects_[o].count = counts[o];
    MaterialRange& m = materials_[o];
    m.first = first;
    m.count = counts[o];
    m.material = group_factories_[o](counts[o]);
    const std::span<Real> state = m.material->state();
    std::copy(states[o].begin(), states[o].begin() + std::min(states[o].size(), state.size()),
              state.begin());
    first += counts[o];
  }
  particles_.stress.assign(stores_stress_ ? particles_.size() : 0, StoredMat3::Zero());
}

Real Simulation::cfl_bound(Real cfl) const {
  Real c = 0, nu = 0;
  for (const auto& m : materials_) {
    if (m.count == 0) continue;
    c = std::max(c, m.material->max_wave_speed(slice(particles_.F, m)));
    nu = std::max(nu, m.material->max_kinematic_viscosity(slice(particles_.F, m)));
  }
  Real speed = max_speed();
  if (domain_) {
    c = domain_->max_all(c);
    nu = domain_->max_all(nu);
    speed = domain_->max_all(speed);
  }
  // dt <= C h / (c + |v|max) (references.md, "Time step"); with viscosity also the explicit
  // diffusion bound dt <= h^2 / (6 nu) (docs/materials.md, "Water").
  const Real h = grid_.h.minCoeff(), bound = cfl * h / (c + speed);
  return nu > 0 ? std::min(bound, h * h / (6 * nu)) : bound;
}

Real Simulation::stable_dt() const {
  const SimulationDesc& s = scene_.simulation;
  if (!s.cfl) return *s.dt;
  const Real bound = cfl_bound(*s.cfl);
  return s.dt ? std::min(*s.dt, bound) : bound;
}

Real Simulation::timed_stable_dt() {
  const auto t0 = std::chrono::steady_clock::now();
  const Real dt = stable_dt();
  bound_seconds_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return dt;
}

std::vector<std::pair<std::string, double>> Simulation::stage_seconds() const {
  std::vector<std::pair<std::string, double>> out;
  if (scene_.simulation.cfl) out.emplace_back("cfl_bound", bound_seconds_);
  for (const Stage& st : stages_) out.emplace_back(st.name, st.seconds);
  return out;
}

void Simulation::substep(Real dt) {
  using clock = std::chrono::steady_clock;
  for (Stage& st : stages_) {
    const auto t0 = clock::now();
    st.run(dt);
    st.seconds += std::chrono::duration<double>(clock::now() - t0).count();
  }
  time_ += dt;
  ++substeps_;
  ++state_;
}

Real Simulation::max_speed() const {
  Real v2 = 0;
  const std::ptrdiff_t n = static_cast<std::ptrdiff_t>(particles_.size());
#pragma omp parallel for schedule(static) reduction(max : v2) if (n >= kParallelMinItems)
  for (std::ptrdiff_t q = 0; q < n; ++q) v2 = std::max(v2, particles_.v[q].squaredNorm());
  return std::sqrt(v2);
}

Real Simulation::kinetic_energy() const {
  return sum_chunks(particles_.size(), [&](std::size_t q) {
    return 0.5 * particles_.mass(q) * particles_.v[q].squaredNorm();
  });
}

Real Simulation::total_energy() const {
  const Vec3 g = scene_.simulation.gravity;
  const Real gravitational = sum_chunks(particles_.size(), [&](std::size_t q) {
    return -particles_.mass(q) * g.dot(particles_.x[q] - grid_.origin);
  });
  return kinetic_energy() + elastic_energy() + gravitational;
}

std::size_t Simulation::first_nonfinite_particle() const {
  for (std::size_t q = 0; q < particles_.size(); ++q)
    if (!particles_.x[q].allFinite() || !particles_.v[q].allFinite() ||
        !particles_.F[q].allFinite())
      return q;
  return particles_.size();
}

std::size_t Simulation::fastest_particle() const {
  std::size_t best = 0;
  for (std::size_t q = 1; q < particles_.size(); ++q)
    if (particles_.v[q].squaredNorm() > particles_.v[best].squaredNorm()) best = q;
  return best;
}

const std::vector<Real>& Simulation::range_elastic_energies() const {
  if (energy_state_ != state_) {
    range_energy_.clear();
    for (const auto& m : materials_)
      range_energy_.push_back(
          m.count == 0 ? Real(0)
                       : m.material->elastic_energy(slice(particles_.F, m),
                                                    particles_.volume0(m.first)));
    energy_state_ = state_;
  }
  return range_energy_;
}

Real Simulation::elastic_energy() const {
  Real e = 0;
  for (Real r : range_elastic_energies()) e += r;
  return e;
}

}  // namespace mpm
