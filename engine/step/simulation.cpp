#include "engine/step/simulation.h"

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <span>
#include <utility>

#include "engine/core/huge_pages.h"
#include "engine/core/reduce.h"
#include "engine/scene/mesh.h"
#include "engine/scene/sampling.h"
#include "engine/step/initial_state.h"
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
void check_memory(double bytes, const FileLoc& loc, const std::string& key,
                  const std::string& what) {
  const double have = static_cast<double>(sysconf(_SC_PHYS_PAGES)) * sysconf(_SC_PAGE_SIZE);
  if (bytes > 0.8 * have) {
    char buf[160];
    std::snprintf(buf, sizeof buf, " needs %.3g GB of memory; this machine has %.3g GB",
                  bytes / 1e9, have / 1e9);
    throw SceneError(loc, key, what + buf);
  }
}

/// Throws SceneError if the grid of `scene` cannot be stored or sorted: the grid's node
/// storage follows the particles, and what covers the domain is its page table (one int per
/// 4^3-node block) and at worst the sort's count per cell of the particles' box.
void check_grid_size(const SceneDesc& scene) {
  const Vec3 blocks =
      (scene.grid.dims + Vec3i::Constant(Grid::kBlockEdge)).cast<Real>() / Grid::kBlockEdge;
  const double cells = scene.grid.dims.cast<double>().prod();
  const std::string grid_name = "the grid of " + std::to_string(scene.grid.dims.x()) + " x " +
                                std::to_string(scene.grid.dims.y()) + " x " +
                                std::to_string(scene.grid.dims.z()) + " cells";
  check_memory((blocks.prod() + cells) * sizeof(std::int32_t), scene.grid.loc, "grid.dims",
               grid_name);
  if (cells >= 4294967296.0)  // the sort's cell keys are 32-bit
    throw SceneError(scene.grid.loc, "grid.dims",
                     grid_name + " has more than 2^32 cells, the most the sort can key");
}

/// The closed mesh of object `od` (scene key `key`), placed in the world.
TriangleMesh object_mesh(const ObjectDesc& od, const std::string& key) {
  TriangleMesh mesh;
  try {
    mesh = load_mesh(od.mesh);
  } catch (const MeshError& e) {
    throw SceneError(od.mesh_loc, key + ".mesh", e.what());
  }
  if (const std::string why = closedness_problem(mesh); !why.empty())
    throw SceneError(od.mesh_loc, key + ".mesh", "'" + od.mesh.string() + "': " + why);
  transform_mesh(mesh, od.scale, od.rotation_deg, od.offset);
  return mesh;
}

/// The particle positions of object o of `scene` (scene key `key`), sampled inside its `mesh`;
/// SceneError when the object does not lie inside the grid's interior, could not fit in
/// memory or samples no particle.
std::vector<Vec3> sample_object(const SceneDesc& scene, std::size_t o, const std::string& key,
                                const TriangleMesh& mesh) {
  const ObjectDesc& od = scene.objects[o];
  const Vec3 h = scene.grid.spacing();
  const Vec3 interior_lo = scene.grid.origin + scene.grid.buffer * h;
  const Vec3 interior_hi = scene.grid.max - scene.grid.buffer * h;
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
      sample_inside(mesh, scene.grid, od.particles_per_cell, od.sampling == Sampling::regular,
                    scene.simulation.seed, o);
  for (const Vec3& x : points)
    if ((x.array() < interior_lo.array()).any() || (x.array() > interior_hi.array()).any())
      throw outside("partly outside");
  if (points.empty())
    throw SceneError(od.loc, key,
                     "object '" + od.name + "' samples zero particles: it spans " +
                         corners(box.min(), box.max()) + ", less than the particle spacing");
  return points;
}

/// Appends object o of `scene`, sampled at `points` (freed here), to the particle arrays `P`
/// with its initial velocity, F = I and its mass and volume; returns its ObjectInfo.
ObjectInfo append_particles(const SceneDesc& scene, std::size_t o, std::vector<Vec3> points,
                            Particles& P) {
  const ObjectDesc& od = scene.objects[o];
  const Real cell_volume = scene.grid.spacing().prod();
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
  return info;
}

/// Sets `rest_depth` (by particle id, ContactState::rest_depth) for the particles `info` of an
/// elastic object: each one's depth below the surface of its placed `mesh`, where it is within
/// kRestDepthCap half spacings.
void add_rest_depth(const TriangleMesh& mesh, const Particles& P, const ObjectInfo& info,
                    std::vector<Real>& rest_depth) {
  const Real spacing = std::cbrt(P.object_volume0.back());
  const std::vector<Real> depth = depth_below_surface(mesh, {P.x.data() + info.first, info.count},
                                                      spacing / 4, kRestDepthCap * spacing / 2);
  rest_depth.resize(P.size(), -1);
  std::copy(depth.begin(), depth.end(), rest_depth.begin() + info.first);
}

/// Object `od` (scene key `key`, particles `info` of `group`) at rest under the scene's
/// gravity (initial_stress: gravity); SceneError when it cannot be.
void settle(const SceneDesc& scene, const ObjectDesc& od, const std::string& key,
            const ObjectInfo& info, const MaterialGroup& group, Particles& P) {
  try {
    settle_under_gravity(scene.simulation.gravity, info.density, std::cbrt(P.object_volume0.back()),
                         group, {P.x.data() + info.first, info.count},
                         {P.F.data() + info.first, info.count});
  } catch (const std::exception& e) {
    throw SceneError(od.loc, key + ".initial_stress", "object '" + od.name + "': " + e.what());
  }
}

/// The registered material of object `od` (scene key `key`); SceneError when unknown.
const MaterialInfo& object_material(const MaterialRegistry& registry, const ObjectDesc& od,
                                    const std::string& key) {
  const MaterialInfo* mat = registry.find(od.material);
  if (!mat) throw SceneError(od.loc, key + ".material", "unknown material '" + od.material + "'");
  return *mat;
}

/// The material group of object `od` (scene key `key`, particles `info` at `x`) from `mat`'s
/// factory; a factory may reject a combination of parameters by throwing (docs/materials.md),
/// which becomes a SceneError at the object.
std::unique_ptr<MaterialGroup> create_group(const MaterialInfo& mat, const ObjectDesc& od,
                                            const std::string& key, const ObjectInfo& info,
                                            const Vec3* x, std::uint64_t seed) {
  std::unique_ptr<MaterialGroup> group;
  try {
    group = mat.create(od.params, GroupInfo{info.density, info.count, {x, info.count}, seed});
  } catch (const std::exception& e) {
    throw SceneError(od.loc, key,
                     "material '" + od.material + "' rejects the parameters of " + "object '" +
                         od.name + "': " + e.what());
  }
  if (!group)
    throw SceneError(od.loc, key, "material '" + od.material + "' built no material group");
  return group;
}

}  // namespace

std::unique_ptr<Simulation> Simulation::create(const SceneDesc& scene,
                                               const MaterialRegistry& registry) {
  check_grid_size(scene);
  std::unique_ptr<Simulation> sim(new Simulation(scene));
  Particles& P = sim->particles_;
  for (std::size_t o = 0; o < scene.objects.size(); ++o) {
    const ObjectDesc& od = scene.objects[o];
    const std::string key = "objects[" + std::to_string(o) + "]";
    const TriangleMesh mesh = object_mesh(od, key);
    const ObjectInfo info = append_particles(scene, o, sample_object(scene, o, key, mesh), P);
    const MaterialInfo& mat = object_material(registry, od, key);
    std::unique_ptr<MaterialGroup> group =
        create_group(mat, od, key, info, P.x.data() + info.first, scene.simulation.seed);
    // Contact at the particles: the surface particles of an elastic body take their depth
    // below its surface as their radius (engine/step/contact.h).
    if (scene.simulation.contact == Contact::particles && !group->has_plasticity())
      add_rest_depth(mesh, P, info, sim->contact_.rest_depth);
    if (od.initial_stress == InitialStress::gravity) settle(scene, od, key, info, *group, P);
    const std::size_t n = info.count;
    const Real density = info.density;
    sim->state_stride_.push_back(group->state().size() / n);
    sim->group_factories_.push_back(
        [create = mat.create, params = od.params, density](std::size_t count) {
          return create(params, GroupInfo{density, count});
        });
    sim->materials_.push_back({info.first, n, std::move(group)});
    sim->objects_.push_back(info);
  }
  if (!sim->contact_.rest_depth.empty()) sim->contact_.rest_depth.resize(P.size(), -1);
  // The walls' ghost weights follow the stress scatter's weights.
  using ForceWeights = ContactState::ForceWeights;
  sim->contact_.force_weights =
      scene.simulation.quadrature == Quadrature::domain ? ForceWeights::domain
      : scene.simulation.transfer == Transfer::mls      ? ForceWeights::mls
                                                        : ForceWeights::gradient;
  sim->walls_ = build_wall_planes(scene.walls);
  // Mesh level sets get voxels of half the cell size.
  sim->colliders_ = build_colliders(scene.walls, sim->grid_.h.minCoeff() / 2);
  sim->build_stages();
  return sim;
}

void Simulation::add_stage(std::string name, std::function<void(Real)> fn) {
  // With more than one rank a stage's exception is kept in the domain and the rank's later
  // compute stages are skipped, while its exchanges still run (the other ranks wait in them):
  // run_frames then stops every rank at the end of the substep (docs/distributed.md).
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
}

void Simulation::add_exchange(std::string name, std::function<void(Real)> fn) {
  stages_.push_back({std::move(name), std::move(fn), 0.0});
}

std::vector<BatchModel> Simulation::lane_models() const {
  std::vector<BatchModel> models;
  if (!scene_.simulation.simd) return models;
  for (const auto& m : materials_) {
    BatchModel b = m.material->batch_model();
    if (!simd::supports_stress(b)) b = BatchModel{};
    if (b.kind == BatchModel::Kind::none && m.material->has_lane_stress()) {
      b.kind = BatchModel::Kind::group;  // the group's own lane kernel (a plugin's)
      b.group = m.material.get();
    }
    b.first = m.first;
    models.push_back(b);
  }
  return models;
}

bool Simulation::add_stress_stage() {
  const SimulationDesc& s = scene_.simulation;
  // The stress of each group (object), chosen here once per group: with simulation.simd, a
  // group whose model has an engine SIMD kernel gets it folded into the SIMD scatter (no
  // stress array, no pass), or, where the scatter is scalar (FLIP), run as its own SIMD pass;
  // any other group runs its compute_stress into Particles::stress. The models themselves are
  // taken at each substep (lane_models): their state moves when particles migrate.
  const bool fold =
      s.simd && s.quadrature == Quadrature::point && simd::supports(s.transfer, s.kernel, grid_);
  const std::vector<BatchModel> models = lane_models();
  const bool any_lanes = std::any_of(models.begin(), models.end(), [](const BatchModel& b) {
    return b.kind != BatchModel::Kind::none;
  });
  const bool stored = !fold || std::any_of(models.begin(), models.end(), [](const BatchModel& b) {
    return b.kind == BatchModel::Kind::none;
  });
  // Only what the scene calls for is stored.
  stores_stress_ = stored;
  particles_.stress.assign(stored ? particles_.size() : 0, StoredMat3::Zero());
  particles_.stress.shrink_to_fit();
  if (stored)
    add_stage("compute_stress", [this, fold](Real) {
      const std::vector<BatchModel> lanes = lane_models();
      for (std::size_t g = 0; g < materials_.size(); ++g) {
        const bool in_lanes = g < lanes.size() && lanes[g].kind != BatchModel::Kind::none;
        if (in_lanes && fold) continue;  // the scatter computes it
        const auto& m = materials_[g];
        if (m.count == 0) continue;  // an object with no particles on this rank
        const auto F = slice(std::as_const(particles_.F), m);
        const Real v0 = particles_.volume0(m.first);
        if (in_lanes && simd::supports_stress(lanes[g]))
          simd::stress(lanes[g], F, v0, slice(particles_.stress, m));
        else
          m.material->compute_stress(F, v0, slice(particles_.stress, m));
      }
    });
  return fold && any_lanes;
}

void Simulation::add_boundary_stages() {
  if (scene_.simulation.contact == Contact::nodes) {
    // Walls act on the grid velocities of the end of the substep: place them at time + dt.
    if (!walls_.empty())
      add_stage("walls", [this](Real dt) { wall_work_ += apply_walls(walls_, time_ + dt, grid_); });
    if (!colliders_.empty())
      add_stage("colliders",
                [this](Real dt) { wall_work_ += apply_colliders(colliders_, time_ + dt, grid_); });
    add_stage("domain_boundary", [this](Real) { apply_domain_boundary(grid_); });
    if (domain_)
      add_exchange("halo_velocity", [this](Real) { domain_->return_ghost_velocities(grid_); });
    return;
  }
  // With more than one rank the ghosts take their owners' mass and velocity first: contact
  // reads the nodes around every contact point.
  if (domain_)
    add_exchange("halo_velocity", [this](Real) { domain_->return_ghost_velocities(grid_); });
  // Walls and colliders act where the particles touch them (engine/step/contact.h).
  const ContactSettings contact_settings{
      .iterations = scene_.simulation.contact_iterations,
      .spectral_radius = scene_.simulation.contact_spectral_radius};
  if (!walls_.empty() || !colliders_.empty())
    add_stage("contact", [this, contact_settings](Real dt) {
      const SimulationDesc& sd = scene_.simulation;
      const Kernel kernel = sd.kernel;
      // On one process, with the SIMD gather next and a solve of some size last substep, the
      // particles no contact can reach are gathered beside the contact (split_gather.h);
      // grid_to_particles gathers the rest.
      if (!domain_) {
        const auto contact = [&](const std::vector<IndexRange>* search) {
          wall_work_ +=
              apply_contact(walls_, colliders_, contact_settings, kernel, time_, dt, particles_,
                            grid_, contact_, contact_memory_, search, speeds_for_contact_);
        };
        const bool split =
            sd.simd && sd.quadrature != Quadrature::domain &&
            contact_.size() >= split_gather_.min_contacts &&
            simd::supports(sd.transfer, kernel, grid_) &&
            gather_beside(contact, walls_, colliders_,
                          buffer_layers_behind_walls(walls_, time_ + dt, grid_), sd.transfer,
                          kernel, time_, dt, grid_, particles_, split_gather_);
        if (!split) contact(nullptr);
        return;
      }
      find_contacts(walls_, colliders_, kernel, time_, dt, particles_, grid_, contact_);
    });
  // The solve over every rank's contacts is collective: a rank whose stages failed takes
  // part with none.
  if (domain_ && (!walls_.empty() || !colliders_.empty()))
    add_exchange("contact_solve", [this, contact_settings](Real dt) {
      if (!domain_->failure().empty()) contact_.clear();
      wall_work_ += domain_->solve_contact(contact_settings, dt, contact_, grid_, contact_memory_);
    });
  // The buffer yields to the walls that cover its sides (walls.h).
  add_stage("domain_boundary", [this](Real dt) {
    apply_domain_boundary(buffer_layers_behind_walls(walls_, time_ + dt, grid_), grid_);
  });
}

void Simulation::add_domain_scatter_stages() {
  add_stage("fit_pressure", [this](Real) {
    pressure_.resize(particles_.size());
    pressure_gradient_.resize(particles_.size());
    particle_pressures(particles_, pressure_);
    fit_linear(particles_, order_, grid_, pressure_, fits_, {}, pressure_gradient_);
  });
  add_stage("particles_to_grid", [this](Real dt) {
    domain_particles_to_grid(particles_, order_, scene_.simulation.transfer, pressure_gradient_, dt,
                             grid_);
  });
}

void Simulation::add_domain_gather_stages() {
  // Each particle's volume change is replaced by the nodal fits' blend of it: MLS's C misses
  // the hydrostatic strain's rate near a free surface, and with any transfer a pattern of
  // particle pressures the nodes do not see would otherwise grow by the floor
  // (docs/accuracy.md, "The pool's top layer, fixed").
  add_stage("record_volume", [this](Real) {
    j_old_.resize(particles_.size());
    const std::ptrdiff_t n = static_cast<std::ptrdiff_t>(particles_.size());
#pragma omp parallel for schedule(static) if (n >= kParallelMinItems)
    for (std::ptrdiff_t q = 0; q < n; ++q) j_old_[q] = to_real(particles_.F[q]).determinant();
  });
  // Gathered at the positions the particles were sorted at (the fits' slabs), then advected.
  add_stage("grid_to_particles", [this](Real dt) {
    const SimulationDesc& sd = scene_.simulation;
    domain_grid_to_particles(grid_, sd.transfer, sd.flip_blend, dt, particles_);
  });
  add_stage("smooth_volume_change", [this](Real) {
    smooth_volume_change(order_, grid_, j_old_, fits_, fit_scratch_, particles_);
  });
  add_stage("advect", [this](Real dt) {
    last_advect_ = advect_particles(dt, grid_, particles_);
    clamped_total_ += last_advect_.clamped;
  });
}

void Simulation::build_stages() {
  const SimulationDesc& s = scene_.simulation;
  stages_.clear();
  const bool domain_quadrature = s.quadrature == Quadrature::domain;
  add_stage("sort", [this, domain_quadrature](Real) {
    sort_particles(particles_, scene_.simulation.kernel, grid_, order_,
                   domain_quadrature ? kDomainReach : 0);
  });
  // With more than one rank: the previous rank's ghost blocks get storage here too.
  if (domain_) add_exchange("halo_blocks", [this](Real) { domain_->share_ghost_blocks(grid_); });
  const bool fold = add_stress_stage();
  if (domain_quadrature) {
    add_domain_scatter_stages();
  } else {
    add_stage("particles_to_grid", [this, fold](Real dt) {
      const SimulationDesc& sd = scene_.simulation;
      particles_to_grid(particles_, order_, sd.transfer, sd.kernel, dt, grid_,
                        sd.simd ? TransferPath::simd : TransferPath::scalar,
                        fold ? lane_models() : std::vector<BatchModel>{});
    });
  }
  // Between the transfers, where v and C are dead unless FLIP blends the old v. It spends the
  // sorted order, which the domain quadrature's volume fits still need after the gather.
  if (s.reorder_every > 0 && !domain_quadrature)
    add_stage("reorder", [this](Real) {
      if (substeps_ % scene_.simulation.reorder_every != 0) return;
      std::vector<ReorderRange> ranges;
      for (auto& m : materials_)  // an object with no particles here (other ranks) has none
        if (m.count > 0) ranges.push_back({m.first, m.count, m.material->state()});
      reorder_particles(ranges, scene_.simulation.transfer == Transfer::flip, order_, particles_);
    });
  if (domain_) add_exchange("halo_sum", [this](Real) { domain_->add_ghost_sums(grid_); });
  // Gravity in the same pass over the nodes as the momentum's division, except for FLIP, whose
  // old velocity is the one before every force.
  const bool gravity = s.gravity.squaredNorm() > 0, flip = s.transfer == Transfer::flip;
  // The contact search bounds closing speeds by the block speeds, which the update can set in
  // its own pass where the contact stage comes next (one rank, no FLIP forces, no damping).
  const bool contact_next = s.contact == Contact::particles && !domain_ && !flip &&
                            !(s.damping > 0) && (!walls_.empty() || !colliders_.empty());
  speeds_for_contact_ = contact_next ? &block_speeds_ : nullptr;
  if (gravity && !flip)
    add_stage("grid_update_gravity", [this](Real dt) {
      grid_update(grid_, dt * scene_.simulation.gravity, speeds_for_contact_);
    });
  else
    add_stage("grid_update",
              [this](Real) { grid_update(grid_, Vec3::Zero(), speeds_for_contact_); });
  // PIC and APIC scatter the stress force as an impulse (see particles_to_grid).
  if (flip) add_stage("stress_forces", [this](Real dt) { apply_stress_forces(dt, grid_); });
  if (gravity && flip)
    add_stage("gravity", [this](Real dt) { apply_gravity(dt, scene_.simulation.gravity, grid_); });
  if (s.damping > 0)
    add_stage("damping", [this](Real dt) { apply_damping(dt, scene_.simulation.damping, grid_); });
  add_boundary_stages();
  // Advection runs inside the gather: on the SIMD path each lane set is advected while its x
  // and v are in cache (the plasticity stage below reads and writes only F and its own state,
  // so the order of the two does not matter).
  if (domain_quadrature) {
    add_domain_gather_stages();
  } else {
    add_stage("grid_to_particles", [this](Real dt) {
      const SimulationDesc& sd = scene_.simulation;
      if (split_gather_.pending)
        gather_rest(grid_, sd.transfer, sd.kernel, dt, particles_, split_gather_, &last_advect_);
      else
        grid_to_particles(grid_, sd.transfer, sd.kernel, sd.flip_blend, dt, particles_,
                          sd.simd ? TransferPath::simd : TransferPath::scalar, &last_advect_);
      clamped_total_ += last_advect_.clamped;
    });
  }
  const bool plastic = std::any_of(materials_.begin(), materials_.end(),
                                   [](const auto& m) { return m.material->has_plasticity(); });
  if (plastic)
    add_stage("plasticity", [this](Real dt) {
      const std::vector<BatchModel> lanes = lane_models();
      for (std::size_t g = 0; g < materials_.size(); ++g) {
        auto& m = materials_[g];
        if (!m.material->has_plasticity()) continue;
        if (g < lanes.size() && simd::supports_projection(lanes[g]))
          simd::project(lanes[g], slice(particles_.F, m), m.material->state());
        else
          m.material->apply_plasticity_step(slice(particles_.F, m), dt);
      }
    });
  // The run's checks see every rank's advection; particles move to their new slab's rank.
  if (domain_ && domain_->test_failure_requested())
    add_stage("test_failure", [this](Real) { domain_->test_failure_point(substeps_ + 1); });
  if (domain_)
    add_exchange("migrate", [this](Real) {
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
  const std::vector<BatchModel> lanes = lane_models();
  for (std::size_t g = 0; g < materials_.size(); ++g) {
    const auto& m = materials_[g];
    if (m.count == 0) continue;
    const bool in_lanes = g < lanes.size() && simd::supports_wave_speed(lanes[g]);
    c = std::max(c, in_lanes ? simd::max_wave_speed(lanes[g], slice(particles_.F, m))
                             : m.material->max_wave_speed(slice(particles_.F, m)));
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
  if (huge_pages_seconds_ >= 0) out.emplace_back("huge_pages", huge_pages_seconds_);
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
  // Once, after the first substep has sized the stages' arrays; timed as "huge_pages".
  if (huge_pages_seconds_ < 0) {
    const auto t0 = clock::now();
    advise_heap_huge_pages();
    huge_pages_seconds_ = std::chrono::duration<double>(clock::now() - t0).count();
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
          m.count == 0
              ? Real(0)
              : m.material->elastic_energy(slice(particles_.F, m), particles_.volume0(m.first)));
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
