#include "engine/parallel/domain.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <string>
#include <unordered_map>

#include "engine/core/error.h"
#include "engine/parallel/comm.h"
#include "engine/parallel/particle_fields.h"
#include "engine/step/contact.h"
#include "engine/step/grid.h"
#include "engine/step/kernels.h"
#include "engine/step/simulation.h"
#include "engine/step/transfer.h"

namespace mpm::parallel {

namespace {

constexpr int kBlockBits = Grid::kBlockBits;

/// Appends the bytes of `value` to `buf`.
template <class T>
void put(std::vector<char>& buf, const T& value) {
  const std::size_t at = buf.size();
  buf.resize(at + sizeof(T));
  std::memcpy(buf.data() + at, static_cast<const void*>(&value), sizeof(T));
}

/// Reads a T from `buf` at `pos` and advances `pos`.
template <class T>
T take(const std::vector<char>& buf, std::size_t& pos) {
  T value;
  std::memcpy(static_cast<void*>(&value), buf.data() + pos, sizeof(T));
  pos += sizeof(T);
  return value;
}

bool keeps_affine(const Simulation& sim) {
  const Transfer t = sim.scene().simulation.transfer;
  return t == Transfer::apic || t == Transfer::mls;
}

/// Block layer of each particle's stencil base node along `axis`.
std::vector<int> base_layers(const Simulation& sim, int axis) {
  const Particles& p = sim.particles();
  const Grid& g = sim.grid();
  std::vector<int> layer(p.size());
  dispatch_kernel(sim.scene().simulation.kernel, [&]<Kernel K>() {
    for (std::size_t q = 0; q < p.size(); ++q)
      layer[q] = stencil_base<K>(p.x[q], g.origin, g.inv_h)[axis] >> kBlockBits;
  });
  return layer;
}

/// One rank's contacts and the nodes they reach (`local`), packed for the solve on rank 0.
std::vector<char> pack_contacts(const ContactState& local) {
  std::vector<char> buf;
  const int S = local.stencil;
  put(buf, local.size());
  put(buf, S);
  put(buf, local.node_velocity.size());
  for (std::size_t c = 0; c < local.size(); ++c) {
    put(buf, local.id[c]);
    put(buf, local.normal[c]);
    put(buf, local.wall_velocity[c]);
    put(buf, local.gap[c]);
    put(buf, local.boundary[c]);
    put(buf, local.friction[c]);
    put(buf, local.patch[c]);
    for (int t = 0; t < S; ++t) {
      put(buf, local.weights[c * S + t]);
      put(buf, local.nodes[c * S + t]);
    }
  }
  for (std::size_t i = 0; i < local.node_velocity.size(); ++i) {
    put(buf, local.node_key[i]);
    put(buf, local.node_velocity[i]);
    put(buf, local.node_inv_mass[i]);
  }
  return buf;
}

/// Every rank's packed contacts (`in`, pack_contacts, in rank order) as one set: nodes merged
/// by key (a ghost and its owner hold the same mass and velocity after halo_velocity),
/// contacts in rank order; `patches` wall and object patches.
ContactState merge_contacts(const std::vector<std::vector<char>>& in, std::size_t patches) {
  const int n = static_cast<int>(in.size());
  ContactState all;
  all.patches = patches;
  all.node_velocity.assign(1, Vec3::Zero());
  all.node_inv_mass.assign(1, 0);
  all.node_key.assign(1, ~std::uint64_t{0});
  std::unordered_map<std::uint64_t, std::uint32_t> merged;
  for (int r = 0; r < n; ++r) {
    const std::vector<char>& b = in[r];
    std::size_t pos = 0;
    const auto nc = take<std::size_t>(b, pos);
    const int s = take<int>(b, pos);
    const auto nn = take<std::size_t>(b, pos);
    if (nc == 0) continue;
    all.stencil = s;
    const std::size_t first = all.size();
    std::vector<std::uint32_t> refs;
    for (std::size_t c = 0; c < nc; ++c) {
      all.id.push_back(take<std::uint32_t>(b, pos));
      all.normal.push_back(take<Vec3>(b, pos));
      all.wall_velocity.push_back(take<Vec3>(b, pos));
      all.gap.push_back(take<Real>(b, pos));
      all.boundary.push_back(take<Boundary>(b, pos));
      all.friction.push_back(take<Real>(b, pos));
      all.patch.push_back(take<std::uint32_t>(b, pos));
      for (int t = 0; t < s; ++t) {
        all.weights.push_back(take<Real>(b, pos));
        refs.push_back(take<std::uint32_t>(b, pos));
      }
    }
    std::vector<std::uint32_t> id(nn, 0);
    for (std::size_t i = 0; i < nn; ++i) {
      const auto key = take<std::uint64_t>(b, pos);
      const auto v = take<Vec3>(b, pos);
      const auto inv_m = take<Real>(b, pos);
      if (key == ~std::uint64_t{0}) continue;  // the rank's "no node" entry
      const auto [it, added] = merged.emplace(key, static_cast<std::uint32_t>(all.node_key.size()));
      if (added) {
        all.node_key.push_back(key);
        all.node_velocity.push_back(v);
        all.node_inv_mass.push_back(inv_m);
      }
      id[i] = it->second;
    }
    for (std::size_t e = 0; e < refs.size(); ++e) all.nodes.push_back(id[refs[e]]);
    all.particle.resize(first + nc);  // unused by the solve
    all.point.resize(first + nc);
  }
  return all;
}

}  // namespace

int Slabs::owner_of_layer(int layer) const {
  const auto it = std::upper_bound(first_layer.begin() + 1, first_layer.end() - 1, layer);
  return static_cast<int>(it - (first_layer.begin() + 1));
}

Slabs balanced_slabs(const std::vector<std::uint64_t>& per_layer, int ranks, int axis) {
  const int layers = static_cast<int>(per_layer.size());
  Slabs s;
  s.axis = axis;
  s.first_layer.assign(ranks + 1, 0);
  s.first_layer[ranks] = layers;
  std::uint64_t total = 0;
  for (std::uint64_t c : per_layer) total += c;
  std::uint64_t before = 0;  // particles in layers [0, l)
  int l = 0;
  for (int r = 1; r < ranks; ++r) {
    // The first layer whose prefix reaches r N / ranks (integer arithmetic: no rounding
    // drift), or the one before it if that prefix is nearer.
    const std::uint64_t target = static_cast<std::uint64_t>(r) * total;
    while (l < layers && before * ranks < target) before += per_layer[l++];
    int bound = l;
    if (l > 0 && target - (before - per_layer[l - 1]) * ranks < before * ranks - target)
      bound = l - 1;
    s.first_layer[r] = std::clamp(bound, s.first_layer[r - 1] + 1, layers - (ranks - r));
  }
  return s;
}

std::shared_ptr<Domain> Domain::create(const Simulation& sim) {
  const Grid& g = sim.grid();
  const int n = ranks();
  const Vec3i dims = sim.scene().grid.dims;
  if (sim.scene().simulation.quadrature == Quadrature::domain)  // its fits read no ghosts
    throw SceneError(sim.scene().simulation.quadrature_loc, "simulation.quadrature",
                     "quadrature 'domain' runs on one rank; run without mpirun or use 'point'");
  int axis = 0;
  for (int a = 1; a < 3; ++a)
    if (dims[a] > dims[axis]) axis = a;
  if (g.blocks[axis] < n) {
    const char* names = "xyz";
    throw SceneError(sim.scene().grid.loc, "grid.dims",
                     std::to_string(n) + " ranks need at least " + std::to_string(n) +
                         " slabs of 4 cells along the grid's longest axis (" + names[axis] + ", " +
                         std::to_string(dims[axis]) + " cells: " + std::to_string(g.blocks[axis]) +
                         " slabs); run on fewer ranks or refine the grid");
  }
  auto d = std::shared_ptr<Domain>(new Domain());
  d->slabs_ = balanced_slabs(std::vector<std::uint64_t>(g.blocks[axis], 1), n, axis);
  d->stats_.ranks = n;
  return d;
}

std::vector<int> Domain::owners(const Simulation& sim) const {
  std::vector<int> owner = base_layers(sim, slabs_.axis);
  for (int& o : owner) o = slabs_.owner_of_layer(o);
  return owner;
}

void Domain::share_ghost_blocks(Grid& g) {
  const int me = rank(), n = ranks();
  const int a = slabs_.axis;
  const int ghost_layer = me + 1 < n ? slabs_.first_layer[me + 1] : -1;
  // This rank's ghost blocks, in storage (block) order, as page-table indices.
  std::vector<char> send;
  for (const Vec3i& f : g.block_first)
    if ((f[a] >> kBlockBits) == ghost_layer)
      put<std::int64_t>(send, static_cast<std::int64_t>(g.page(
                                  f.x() >> kBlockBits, f.y() >> kBlockBits, f.z() >> kBlockBits)));
  const std::vector<char> recv = send_receive(send, me + 1 < n ? me + 1 : -1, me - 1);
  std::vector<std::size_t> pages;
  for (std::size_t pos = 0; pos < recv.size();)
    pages.push_back(static_cast<std::size_t>(take<std::int64_t>(recv, pos)));
  // Activate the previous rank's ghost blocks this rank's particles do not touch.
  bool missing = false;
  Vec3i lo = Vec3i::Constant(1 << 30), hi = Vec3i::Constant(-1);
  for (const Vec3i& f : g.block_first) {
    const Vec3i b(f.x() >> kBlockBits, f.y() >> kBlockBits, f.z() >> kBlockBits);
    lo = lo.cwiseMin(b), hi = hi.cwiseMax(b);
  }
  for (std::size_t page : pages) {
    const int bk = static_cast<int>(page % g.blocks.z());
    const int bj = static_cast<int>(page / g.blocks.z() % g.blocks.y());
    const int bi = static_cast<int>(page / g.blocks.z() / g.blocks.y());
    lo = lo.cwiseMin(Vec3i(bi, bj, bk)), hi = hi.cwiseMax(Vec3i(bi, bj, bk));
    if (g.slot[page] < 0) g.slot[page] = 0, missing = true;
  }
  if (missing) g.activate_blocks(lo, hi);
  send_slots_.clear();
  for (std::size_t pos = 0; pos < send.size();)
    send_slots_.push_back(static_cast<std::size_t>(g.slot[take<std::int64_t>(send, pos)]));
  recv_slots_.clear();
  for (std::size_t page : pages) recv_slots_.push_back(static_cast<std::size_t>(g.slot[page]));
}

void Domain::add_ghost_sums(Grid& g) {
  const int me = rank(), n = ranks();
  constexpr int B = Grid::kBlockNodes;
  std::vector<char> send;
  for (std::size_t s : send_slots_)
    for (std::size_t i = s * B; i < (s + 1) * B; ++i) {
      put(send, g.mass[i]);
      put(send, g.velocity[i]);
      if (g.flip) put(send, g.force[i]);
      g.mass[i] = 0;  // the owner's sum is the node's value; the ghost waits for it
      g.velocity[i].setZero();
      if (g.flip) g.force[i].setZero();
    }
  halo_local_ += send.size();
  const std::vector<char> recv = send_receive(send, me + 1 < n ? me + 1 : -1, me - 1);
  std::size_t pos = 0;
  for (std::size_t s : recv_slots_)
    for (std::size_t i = s * B; i < (s + 1) * B; ++i) {
      g.mass[i] += take<Real>(recv, pos);
      g.velocity[i] += take<Vec3>(recv, pos);
      if (g.flip) g.force[i] += take<Vec3>(recv, pos);
    }
}

void Domain::return_ghost_velocities(Grid& g) {
  const int me = rank(), n = ranks();
  constexpr int B = Grid::kBlockNodes;
  std::vector<char> send;
  for (std::size_t s : recv_slots_)
    for (std::size_t i = s * B; i < (s + 1) * B; ++i) {
      put(send, g.mass[i]);
      put(send, g.velocity[i]);
      if (g.flip) put(send, g.velocity_old[i]);
    }
  halo_local_ += send.size();
  const std::vector<char> recv = send_receive(send, me - 1, me + 1 < n ? me + 1 : -1);
  std::size_t pos = 0;
  for (std::size_t s : send_slots_)
    for (std::size_t i = s * B; i < (s + 1) * B; ++i) {
      g.mass[i] = take<Real>(recv, pos);
      g.velocity[i] = take<Vec3>(recv, pos);
      if (g.flip) g.velocity_old[i] = take<Vec3>(recv, pos);
    }
}

Real Domain::solve_contact(const ContactSettings& settings, Real dt, ContactState& local, Grid& g,
                           ContactMemory& memory) {
  const int me = rank(), n = ranks();
  // Every rank's contacts and the nodes they reach, to rank 0.
  std::vector<std::vector<char>> out(n);
  std::vector<char>& buf = out[0];
  buf = pack_contacts(local);
  halo_local_ += buf.size();
  const std::vector<std::vector<char>> in = all_to_all(out);
  // Rank 0 solves them as one set, nodes merged by key (a ghost and its owner hold the same
  // mass and velocity after halo_velocity), contacts in rank order.
  Real work = 0;
  std::vector<std::vector<char>> back(n);
  if (me == 0) {
    ContactState all = merge_contacts(in, local.patches);
    if (all.size() > 0)
      work = mpm::solve_contact(settings, dt, all, memory);
    else
      memory.keep({}, {}, {}, dt);
    std::vector<char> result;
    for (std::size_t i = 1; i < all.node_key.size(); ++i) {
      if (!(all.node_inv_mass[i] > 0)) continue;
      put(result, all.node_key[i]);
      put(result, all.node_velocity[i]);
    }
    for (int r = 0; r < n; ++r) back[r] = result;
    halo_local_ += result.size() * (n - 1);
  }
  // Every rank sets the velocity of each node it stores, owned or ghost.
  const std::vector<std::vector<char>> answer = all_to_all(back);
  const std::vector<char>& b = answer[0];
  const std::uint64_t nz = static_cast<std::uint64_t>(g.nodes.z());
  const std::uint64_t ny = static_cast<std::uint64_t>(g.nodes.y());
  for (std::size_t pos = 0; pos < b.size();) {
    const auto key = take<std::uint64_t>(b, pos);
    const auto v = take<Vec3>(b, pos);
    const int k = static_cast<int>(key % nz), j = static_cast<int>(key / nz % ny),
              i = static_cast<int>(key / nz / ny);
    if (g.slot[g.page(i >> kBlockBits, j >> kBlockBits, k >> kBlockBits)] < 0) continue;
    g.velocity[g.node_index(i, j, k)] = v;
  }
  return work;
}

void Domain::exchange(Simulation& sim, const std::vector<int>& dest) {
  const int me = rank(), n = ranks();
  Particles& p = sim.particles();
  const bool apic = keeps_affine(sim);
  const std::size_t objects = sim.objects().size();
  bool moves = false;
  for (int d : dest) moves |= d != me;
  if (!any_all(moves)) return;

  // Each leaving particle as one record: its fields (visit_particle_fields), then its
  // material state. Packed in memory order, so each object's records are contiguous.
  std::vector<std::vector<char>> out(n);
  for (std::size_t o = 0; o < objects; ++o) {
    const ObjectInfo& info = sim.objects()[o];
    const std::span<Real> state = sim.materials()[o].material->state();
    const std::size_t s = sim.state_stride(o);
    for (std::size_t q = info.first; q < info.first + info.count; ++q) {
      if (dest[q] == me) continue;
      std::vector<char>& buf = out[dest[q]];
      visit_particle_fields(p, apic, [&](const auto& field) { put(buf, field[q]); });
      for (std::size_t k = 0; k < s; ++k) put(buf, state[(q - info.first) * s + k]);
    }
  }
  const std::vector<std::vector<char>> in = all_to_all(out);

  // New order per object: the particles from rank 0, then rank 1, ... (this rank's kept
  // particles in their memory order at its own place): the same on every run.
  Particles next;
  next.object_mass = p.object_mass;
  next.object_volume0 = p.object_volume0;
  std::vector<std::size_t> counts(objects, 0);
  std::vector<std::vector<Real>> states(objects);
  std::vector<std::size_t> cursor(n, 0);
  const auto unpack = [&](const std::vector<char>& buf, std::size_t& pos) {
    visit_particle_fields(next, apic, [&](auto& field) {
      using T = typename std::remove_reference_t<decltype(field)>::value_type;
      field.push_back(take<T>(buf, pos));
    });
  };
  for (std::size_t o = 0; o < objects; ++o) {
    const ObjectInfo& info = sim.objects()[o];
    const std::span<Real> state = sim.materials()[o].material->state();
    const std::size_t s = sim.state_stride(o);
    for (int src = 0; src < n; ++src) {
      if (src == me) {
        // Kept particles go through the same record as moving ones: one field list.
        std::vector<char> rec;
        for (std::size_t q = info.first; q < info.first + info.count; ++q) {
          if (dest[q] != me) continue;
          rec.clear();
          visit_particle_fields(p, apic, [&](const auto& field) { put(rec, field[q]); });
          std::size_t pos = 0;
          unpack(rec, pos);
          for (std::size_t k = 0; k < s; ++k) states[o].push_back(state[(q - info.first) * s + k]);
          ++counts[o];
        }
        continue;
      }
      const std::vector<char>& buf = in[src];
      std::size_t& pos = cursor[src];
      while (pos < buf.size()) {
        std::size_t peek = pos;
        if (take<std::uint32_t>(buf, peek) != o) break;
        unpack(buf, pos);
        for (std::size_t k = 0; k < s; ++k) states[o].push_back(take<Real>(buf, pos));
        ++counts[o];
      }
    }
  }
  sim.replace_particles(std::move(next), counts, std::move(states));
}

void Domain::migrate(Simulation& sim) {
  ++stats_.substeps;
  exchange(sim, owners(sim));
}

AdvectStats Domain::combine(const AdvectStats& local) const {
  AdvectStats all;
  all.clamped = sum_all(static_cast<std::uint64_t>(local.clamped));
  all.nonfinite = sum_all(static_cast<std::uint64_t>(local.nonfinite));
  // A NaN speed on any rank must win the max: send it as infinity.
  all.max_speed = max_all(std::isfinite(local.max_speed) ? static_cast<double>(local.max_speed)
                                                         : std::numeric_limits<double>::infinity());
  return all;
}

void Domain::keep_root_only(Simulation& sim) {
  if (rank() == 0) return;
  Particles none;
  none.object_mass = sim.particles().object_mass;
  none.object_volume0 = sim.particles().object_volume0;
  sim.replace_particles(std::move(none), std::vector<std::size_t>(sim.objects().size(), 0),
                        std::vector<std::vector<Real>>(sim.objects().size()));
  sim.set_totals(0, 0);
}

void Domain::distribute(Simulation& sim) {
  const int n = ranks();
  // The particle count per base layer over all ranks (wherever the particles are: on rank 0
  // after collect(), or on their slabs), the same slabs on every rank, and each particle
  // moved to its new owner by the migration exchange.
  std::vector<std::uint64_t> per_layer(sim.grid().blocks[slabs_.axis], 0);
  for (int l : base_layers(sim, slabs_.axis))
    ++per_layer[std::clamp(l, 0, static_cast<int>(per_layer.size()) - 1)];
  slabs_.first_layer = balanced_slabs(sum_all(std::move(per_layer)), n, slabs_.axis).first_layer;
  exchange(sim, owners(sim));
  // Load balance of this frame: max / mean particles per rank.
  stats_.particles = all_gather(static_cast<std::uint64_t>(sim.particles().size()));
  std::uint64_t total = 0, most = 0;
  for (std::uint64_t c : stats_.particles) total += c, most = std::max(most, c);
  const double imbalance = total > 0 ? static_cast<double>(most) * n / total : 1.0;
  ++stats_.frames;
  imbalance_sum_ += imbalance;
  stats_.imbalance_max = stats_.frames == 1 ? imbalance : std::max(stats_.imbalance_max, imbalance);
  stats_.imbalance_mean = imbalance_sum_ / stats_.frames;
}

void Domain::collect(Simulation& sim) {
  exchange(sim, std::vector<int>(sim.particles().size(), 0));
  collect_counters(sim);
}

void Domain::collect_counters(Simulation& sim) {
  const Real work = sum_all(static_cast<double>(sim.wall_work()));
  const std::uint64_t clamped = sum_all(static_cast<std::uint64_t>(sim.clamped_particles()));
  if (rank() == 0)
    sim.set_totals(work, clamped);
  else
    sim.set_totals(0, 0);
  stats_.comm_seconds = all_gather(comm_stats().seconds);
  stats_.bytes = all_gather(comm_stats().bytes);
  stats_.halo_bytes = sum_all(halo_local_);
}

void Domain::set_failure(const std::string& why) {
  if (failure_.empty()) failure_ = "rank " + std::to_string(rank()) + ", " + why;
}

double Domain::max_all(double x) const {
  return parallel::max_all(x);
}

bool Domain::test_failure_requested() const {
  return parallel::test_failure_requested();
}

void Domain::test_failure_point(std::size_t substeps) const {
  parallel::test_failure_point(substeps);
}

Domain* domain_of(const Simulation& sim) {
  // Domain is the only RankExchange (engine/step/exchange.h).
  return static_cast<Domain*>(sim.domain());
}

}  // namespace mpm::parallel
