#include "engine/step/contact.h"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <limits>
#include <utility>

#include "engine/core/hash.h"
#include "engine/core/idle_help.h"
#include "engine/core/radix_sort.h"
#include "engine/step/domain_quadrature.h"

namespace mpm {

namespace {

/// The key contacts and kept impulses are ordered by: patch, then particle id.
std::uint64_t contact_key(std::uint32_t patch, std::uint32_t id) {
  return std::uint64_t{patch} << 32 | id;
}

/// One wall as the contact search sees it at one particle.
struct WallHit {
  Real distance;  ///< Signed distance of the particle from the wall, m (negative behind it).
  Vec3 normal;    ///< Unit normal into the free side.
  Vec3 velocity;  ///< Wall velocity at the particle, m/s.
  Vec3 point;     ///< The particle's projection on the wall: its contact point.
};

/// Half the particle spacing of each object of `p`, m: a body's outer particles lie that far
/// inside its surface (sampling.cpp), so the surface, not the particle centres, meets a wall.
std::vector<Real> half_spacings(const Particles& p) {
  std::vector<Real> half(p.object_volume0.size());
  for (std::size_t o = 0; o < half.size(); ++o)
    half[o] = Real(0.5) * std::cbrt(p.object_volume0[o]);
  return half;
}

/// The radius of particle q against a wall of normal n (contact.h): half its spacing
/// (`half_spacing`, per object), or on an elastic body's surface its rest depth times |F^T n|,
/// at most 3/4 of the spacing (kRestDepthCap half spacings).
struct ParticleRadius {
  const Particles& p;                     ///< The particles.
  const std::vector<Real>& half_spacing;  ///< Per object, m.
  const std::vector<Real>& rest_depth;    ///< ContactState::rest_depth.

  /// Rest depth of particle q, or -1 if it has none.
  Real depth(std::size_t q) const { return rest_depth.empty() ? -1 : rest_depth[p.id[q]]; }
  /// The largest radius any particle can have: kRestDepthCap half spacings of the most widely
  /// spaced object (0 without objects).
  Real widest() const {
    return half_spacing.empty()
               ? 0
               : kRestDepthCap * *std::max_element(half_spacing.begin(), half_spacing.end());
  }
  /// The largest radius particle q can have against any wall.
  Real most(std::size_t q) const {
    return half_spacing[p.object[q]] * (depth(q) < 0 ? 1 : kRestDepthCap);
  }
  /// The radius against a wall of normal n.
  Real along(std::size_t q, const Vec3& n) const {
    const Real d = depth(q);
    if (d < 0) return half_spacing[p.object[q]];
    return std::min(d * (to_real(p.F[q]).transpose() * n).norm(), most(q));
  }
};

/// How fast the grid can close a gap near a point: per storage block, the largest velocity
/// component of its nodes with mass along each axis, either way, so that a particle still a gap
/// away from a wall is dropped where every node of its stencil closes on the wall slower than
/// that gap over the substep (gather_stencils would drop it too: the velocity at its contact
/// point is a mean of those nodes').
struct GridSpeed {
  const Grid& g;  ///< The grid.
  BlockSpeeds own;  ///< The grid's block speeds made here, if the caller had none.
  /// The block speeds: the caller's (grid_update's, with no velocity changed since) or own.
  const BlockSpeeds& speeds;

  /// The block speeds `given`, or else those of `grid` (block_speeds).
  GridSpeed(const Grid& grid, const BlockSpeeds* given)
      : g(grid), own(given ? BlockSpeeds{} : block_speeds(grid)), speeds(given ? *given : own) {}
  /// The blocks of a caller's last near() and their bound (one per thread).
  struct Last {
    Vec3i lo = Vec3i::Constant(-1), hi = Vec3i::Constant(-2);  ///< No blocks.
    Vec3 n = Vec3::Zero();                                     ///< The normal asked about.
    Real speed = 0;                                            ///< near()'s answer.
  };
  /// The fastest any node within two cells of `x` (any kernel's stencil of a point there)
  /// moves against the normal `n`, m/s (at least 0): over the blocks those nodes lie in (at
  /// most two per axis), the sum over the axes of |n_a| times the largest component against
  /// n_a, which bounds -v.n at every node. Reuses `last` when its blocks and normal are the
  /// same (the particles lie in cell order), else replaces it.
  Real near(const Vec3& x, const Vec3& n, Last& last) const {
    Vec3i lo, hi;
    if (!blocks_near(x, x, lo, hi)) return 0;
    if (lo != last.lo || hi != last.hi || n != last.n) last = {lo, hi, n, near_blocks(lo, hi, n)};
    return last.speed;
  }
  /// The largest near() of any point in the box from `lo` to `hi` (at least 0).
  Real near_box(const Vec3& lo, const Vec3& hi, const Vec3& n) const {
    Vec3i from, to;
    return blocks_near(lo, hi, from, to) ? near_blocks(from, to, n) : 0;
  }
  /// The blocks (`from` to `to`, block coordinates, inclusive) of the nodes within two cells of
  /// the box from `lo` to `hi`; false if there are none (the box lies wholly outside the grid).
  bool blocks_near(const Vec3& lo, const Vec3& hi, Vec3i& from, Vec3i& to) const {
    const Vec3 f = (lo - g.origin).cwiseProduct(g.inv_h), t = (hi - g.origin).cwiseProduct(g.inv_h);
    for (int a = 0; a < 3; ++a) {
      from[a] = std::max(static_cast<int>(std::floor(f[a])) - 1, 0) >> Grid::kBlockBits;
      to[a] = std::min(static_cast<int>(std::floor(t[a])) + 2, g.nodes[a] - 1) >> Grid::kBlockBits;
      if (from[a] > to[a]) return false;
    }
    return true;
  }
  /// near() over the blocks lo to hi (block coordinates, inclusive).
  Real near_blocks(const Vec3i& lo, const Vec3i& hi, const Vec3& n) const {
    Real fastest_in = 0;
    for (int i = lo.x(); i <= hi.x(); ++i)
      for (int j = lo.y(); j <= hi.y(); ++j)
        for (int k = lo.z(); k <= hi.z(); ++k) {
          const std::int32_t s = g.slot[g.page(i, j, k)];
          if (s < 0) continue;
          Real closing = 0;
          for (int a = 0; a < 3; ++a)
            closing += std::abs(n[a]) * speeds.block[s][n[a] > 0 ? 2 * a + 1 : 2 * a];
          fastest_in = std::max(fastest_in, closing);
        }
    return fastest_in;
  }
};

/// A stencil node that takes no part in a contact (outside the grid, unallocated or massless).
constexpr std::size_t kNoNode = Grid::kNoStorage;

/// Whether a particle still a gap away from a wall can reach it within the substep: some node
/// with mass of its contact point's stencil closes on the wall faster than the gap over the
/// substep. The velocity gather_stencils interpolates at the point is a mean of those nodes',
/// so a particle none of them closes fast enough cannot act: it is dropped in the search,
/// before its contact and stencil are stored (at 1M particles on a floor, most candidates that
/// GridSpeed's blocks let through).
template <Kernel K>
struct StencilClosing {
  const Grid& g;  ///< The grid.
  Real dt;        ///< The substep, s.
  /// The last stencil asked about and its closing speed (use one copy per thread): the
  /// particles lie in cell order, so the next one is mostly in the same cell.
  struct Last {
    Vec3i base = Vec3i::Constant(std::numeric_limits<int>::min());  ///< None yet.
    Vec3 n = Vec3::Zero();              ///< The wall normal asked about.
    Vec3 wall_velocity = Vec3::Zero();  ///< The wall velocity asked about, m/s.
    Real closing = 0;                   ///< The fastest closing of its nodes, m/s.
  } last;

  /// True if a node with mass of the stencil at `point` moves against the wall (normal `n`,
  /// velocity `wall_velocity`) faster than `gap` / dt.
  bool operator()(const Vec3& point, const Vec3& n, const Vec3& wall_velocity, Real gap) {
    constexpr int N = KernelTraits<K>::kNodes;
    const Vec3i base = stencil_base<K>(point, g.origin, g.inv_h);
    if (base != last.base || n != last.n || wall_velocity != last.wall_velocity) {
      std::size_t at[N * N * N];
      g.stencil_indices<N, true>(base, at);
      Real closing = 0;
      for (const std::size_t i : at)
        if (i != kNoNode && g.mass[i] > 0)
          closing = std::max(closing, -(g.velocity[i] - wall_velocity).dot(n));
      last = {base, n, wall_velocity, closing};
    }
    return !(last.closing * dt <= gap);
  }
};

/// A wall as the contact search takes it: its condition and how far a particle can close on
/// it within a substep.
struct WallReach {
  Boundary boundary;    ///< The wall's condition.
  Real friction;        ///< Its Coulomb coefficient.
  Real travel;          ///< The farthest a particle's contact point can close on it, m.
  std::uint32_t index;  ///< Its index among the scene's planes, then colliders (its patches).
};

/// Resizes `v` to n entries, reserving a quarter more when it must grow: the stencil buffers
/// keep their memory from substep to substep, and a contact count that creeps up as a body
/// settles reallocates (maps and faults in fresh pages) only now and then.
template <class T>
void resize_kept(std::vector<T>& v, std::size_t n) {
  if (n > v.capacity()) v.reserve(n + n / 4);
  v.resize(n);
}

/// Copies contact `from`'s per-contact fields (not its stencil) over contact `to`'s.
void copy_contact(ContactState& st, std::size_t from, std::size_t to) {
  st.particle[to] = st.particle[from];
  st.id[to] = st.id[from];
  st.point[to] = st.point[from];
  st.normal[to] = st.normal[from];
  st.wall_velocity[to] = st.wall_velocity[from];
  st.gap[to] = st.gap[from];
  st.boundary[to] = st.boundary[from];
  st.friction[to] = st.friction[from];
  st.patch[to] = st.patch[from];
}

/// Keeps the first `n` contacts' per-contact fields, or adds room for more (not their
/// stencils).
void resize_contacts(ContactState& st, std::size_t n) {
  for (auto* v : {&st.particle, &st.id, &st.patch}) v->resize(n);
  for (auto* v : {&st.point, &st.normal, &st.wall_velocity}) v->resize(n);
  st.gap.resize(n);
  st.boundary.resize(n);
  st.friction.resize(n);
}

/// A particle that `hit` found within reach of a wall, before it is appended to the contacts.
struct Candidate {
  std::uint32_t particle;  ///< The particle.
  std::uint32_t wall;      ///< The wall, in `walls` order.
  WallHit hit;             ///< The wall at the particle.
  Real gap;                ///< Distance less the particle's radius, m.
};

/// Appends a contact for every particle and wall w that `scan` finds
/// within reach (the particle's radius bound plus the wall's travel) and that can act:
/// touching, or closing its gap within the substep of `dt` as fast as the grid near its
/// contact point allows: first bounded by the blocks around it (`speed`), then exactly by its
/// stencil's nodes (`closes(point, normal, wall velocity, gap)`, StencilClosing).
/// `scan(first, last, reach, keep)` tests particles [first, last) against every wall, calling
/// `keep(q, w, hit)` for each within `reach[w]` of wall w. Only the particles of `search` are
/// scanned. They go in chunks of at most kChunk, handed out to the threads
/// as they come free (the particles near the walls are seldom spread evenly over the index
/// range). The contacts are appended wall by wall, each in particle order, whatever the thread
/// count: each chunk keeps its own, and the chunks are joined in order.
template <class Scan, class Closes>
void find_contacts(const ParticleRadius& radius, const GridSpeed& speed, Real dt,
                   const std::vector<WallReach>& walls, std::span<const IndexRange> search,
                   Scan&& scan, const Closes& closes, ContactState& st) {
  constexpr std::size_t kChunk = 8192;
  const Particles& p = radius.p;
  if (p.size() == 0 || walls.empty()) return;
  std::vector<IndexRange> piece;
  for (const IndexRange& r : search)
    for (std::size_t q = r.first; q < r.last; q += kChunk)
      piece.push_back({q, std::min(r.last, q + kChunk)});
  const std::ptrdiff_t n = static_cast<std::ptrdiff_t>(p.size());
  const Real widest = radius.widest();
  std::vector<Real> reach(walls.size());
  for (std::size_t w = 0; w < walls.size(); ++w) reach[w] = widest + walls[w].travel;
  const std::size_t nw = walls.size(), objects = radius.half_spacing.size(), base = st.size();
  const std::ptrdiff_t chunks = static_cast<std::ptrdiff_t>(piece.size());
  std::vector<std::vector<Candidate>> found(chunks);
  // Where each chunk's contacts on each wall go: wall by wall, and within a wall chunk by
  // chunk (at[w * chunks + k]).
  std::vector<std::size_t> at(nw * chunks + 1, 0);
  const bool par = n >= kParallelMinItems;
#pragma omp parallel if (par)
  {
    Closes closes_here = closes;  // its own last stencil
    GridSpeed::Last near_last;    // and last blocks
#pragma omp for schedule(dynamic, 1)
    for (std::ptrdiff_t k = 0; k < chunks; ++k) {
      std::vector<Candidate>& mine = found[k];
      scan(static_cast<std::ptrdiff_t>(piece[k].first), static_cast<std::ptrdiff_t>(piece[k].last),
           reach, [&](std::ptrdiff_t q, std::uint32_t w, const WallHit& h) {
             if (h.distance >= radius.most(q) + walls[w].travel) return;
             const Real gap = h.distance - radius.along(q, h.normal);
             if (gap > 0 &&
                 (dt * (speed.near(h.point, h.normal, near_last) + h.velocity.norm()) <= gap ||
                  !closes_here(h.point, h.normal, h.velocity, gap)))
               return;
             mine.push_back({static_cast<std::uint32_t>(q), w, h, gap});
           });
      for (const Candidate& c : mine) ++at[c.wall * chunks + k + 1];
    }  // (a barrier)
#pragma omp single
    {
      at[0] = base;
      for (std::size_t k = 1; k < at.size(); ++k) at[k] += at[k - 1];
      resize_contacts(st, at.back());
    }  // (a barrier)
#pragma omp for schedule(dynamic, 1)
    for (std::ptrdiff_t k = 0; k < chunks; ++k) {
      if (found[k].empty()) continue;
      std::vector<std::size_t> next(nw);
      for (std::size_t w = 0; w < nw; ++w) next[w] = at[w * chunks + k];
      for (const Candidate& c : found[k]) {
        const std::size_t i = next[c.wall]++;
        const std::uint32_t q = c.particle;
        st.particle[i] = q;
        st.id[i] = p.id[q];
        st.point[i] = c.hit.point;
        st.normal[i] = c.hit.normal;
        st.wall_velocity[i] = c.hit.velocity;
        st.gap[i] = c.gap;
        st.boundary[i] = walls[c.wall].boundary;
        st.friction[i] = walls[c.wall].friction;
        st.patch[i] = walls[c.wall].index * static_cast<std::uint32_t>(objects) + p.object[q];
      }
    }
  }
}

/// Scans particles [first, last) of `x` against the planes of normals `normal` through
/// `point`, moving at `velocity`, calling `keep(q, w, hit)` for each particle q within
/// `reach[w]` of plane w, and within `tile_reach(w, lo, hi)` of it, the reach of the contact
/// points in the box from `lo` to `hi`. The particles go in tiles that stay in cache: a plane
/// that the tile's bounding box lies beyond the reach of is skipped (the particles lie in cell
/// order after the reorder stage, so most tiles are small boxes far from every wall), each
/// other plane's distances are one tight loop, and so is the test against the reach of the
/// tile's contact points.
template <class TileReach, class Keep>
void scan_planes(const std::vector<Vec3>& x, const std::vector<Vec3>& normal,
                 const std::vector<Vec3>& point, const std::vector<Vec3>& velocity,
                 std::ptrdiff_t first, std::ptrdiff_t last, const std::vector<Real>& reach,
                 const TileReach& tile_reach, Keep&& keep) {
  constexpr std::ptrdiff_t kTile = 256;
  Real distance[kTile];
  Vec3 on[kTile];
  for (std::ptrdiff_t tile = first; tile < last; tile += kTile) {
    const std::ptrdiff_t m = std::min(kTile, last - tile);
    const Vec3* xt = &x[tile];
    // Four bounds side by side: one is a chain of dependent minima and maxima, four overlap
    // (the same box in any order).
    Vec3 lo4[4] = {xt[0], xt[0], xt[0], xt[0]}, hi4[4] = {xt[0], xt[0], xt[0], xt[0]};
    std::ptrdiff_t i = 1;
    for (; i + 4 <= m; i += 4)
      for (int k = 0; k < 4; ++k) {
        lo4[k] = lo4[k].cwiseMin(xt[i + k]);
        hi4[k] = hi4[k].cwiseMax(xt[i + k]);
      }
    for (; i < m; ++i) {
      lo4[0] = lo4[0].cwiseMin(xt[i]);
      hi4[0] = hi4[0].cwiseMax(xt[i]);
    }
    const Vec3 lo = lo4[0].cwiseMin(lo4[1]).cwiseMin(lo4[2].cwiseMin(lo4[3]));
    const Vec3 hi = hi4[0].cwiseMax(hi4[1]).cwiseMax(hi4[2].cwiseMax(hi4[3]));
    for (std::size_t w = 0; w < normal.size(); ++w) {
      const Vec3 n = normal[w];
      const Real c = n.dot(point[w]), r = reach[w];
      // The box's corner nearest the plane's back.
      const Vec3 near((n.x() > 0 ? lo : hi).x(), (n.y() > 0 ? lo : hi).y(),
                      (n.z() > 0 ? lo : hi).z());
      if (near.dot(n) - c >= r) continue;
      bool any = false;
      for (std::ptrdiff_t i = 0; i < m; ++i) {
        distance[i] = xt[i].dot(n) - c;
        any |= distance[i] < r;
      }
      if (!any) continue;
      // A wall across a grid axis has its contact points exactly on its coordinate, so that
      // they share their ghost rows (gather_stencils).
      int axis;
      const bool across = n.cwiseAbs().maxCoeff(&axis) == 1;
      Vec3 on_lo = Vec3::Constant(std::numeric_limits<Real>::max()), on_hi = -on_lo;
      // The axis a compile-time constant (A, or -1 for none) and the point made from scalars:
      // an element set in a vector goes through memory, and reading the vector back stalls on
      // the store.
      const auto project = [&]<int A>() {
        const Real at = A >= 0 ? point[w][std::max(A, 0)] : 0;
        for (std::ptrdiff_t i = 0; i < m; ++i) {
          if (!(distance[i] < r)) continue;
          const Real d = distance[i];
          const Vec3 o(A == 0 ? at : xt[i].x() - d * n.x(), A == 1 ? at : xt[i].y() - d * n.y(),
                       A == 2 ? at : xt[i].z() - d * n.z());
          on[i] = o;
          on_lo = on_lo.cwiseMin(o);
          on_hi = on_hi.cwiseMax(o);
        }
      };
      switch (across ? axis : -1) {
        case 0:
          project.template operator()<0>();
          break;
        case 1:
          project.template operator()<1>();
          break;
        case 2:
          project.template operator()<2>();
          break;
        default:
          project.template operator()<-1>();
      }
      const Real tight = std::min(r, tile_reach(w, on_lo, on_hi));
      for (std::ptrdiff_t i = 0; i < m; ++i)
        if (distance[i] < tight)
          keep(tile + i, static_cast<std::uint32_t>(w),
               WallHit{distance[i], n, velocity[w], on[i]});
    }
  }
}

/// The normal part of the accumulated impulse of contact c after one projected Jacobi step,
/// from the velocity `u` interpolated at its contact point: a touching particle may not move into
/// the wall (sticky: nor away from it); one still a gap away may close the gap within this
/// substep, no further.
Real normal_impulse(const ContactState& st, std::size_t c, const Vec3& u, Real dt) {
  const Vec3& n = st.normal[c];
  const bool touching = st.gap[c] <= 0;
  const Real target = touching ? 0 : -st.gap[c] / dt;
  const Real ln = st.normal_impulse[c] + (target - (u - st.wall_velocity[c]).dot(n)) * st.inv_k[c];
  return touching && st.boundary[c] == Boundary::sticky ? ln : std::max(ln, Real(0));
}

/// True where contact c is a touching particle of a sticky wall: held, with no friction law.
bool held(const ContactState& st, std::size_t c) {
  return st.gap[c] <= 0 && st.boundary[c] == Boundary::sticky;
}

/// How far the velocity `u` at touching contact c's point is from its normal condition, m/s
/// (0 for a contact still a gap away): its normal velocity relative to the wall, into it, or
/// either way where the contact pushes or is held.
Real violation(const ContactState& st, std::size_t c, const Vec3& u) {
  if (st.gap[c] > 0) return 0;
  const Real off = (u - st.wall_velocity[c]).dot(st.normal[c]);
  return held(st, c) || st.normal_impulse[c] > 0 ? std::abs(off) : std::max(-off, Real(0));
}

/// True where contact c takes part in friction: held, or on a wall with friction.
bool rubs(const ContactState& st, std::size_t c) {
  return held(st, c) || st.friction[c] > 0;
}

/// Rows of ghosts down to N cells behind the wall (N + 1 with a ghost's domain) for a contact
/// of particle spacing `spacing`: beyond, a ghost reaches no node of the stencil.
template <Kernel K>
int ghost_row_count(Real spacing, ContactState::ForceWeights kind, const Grid& g) {
  const int domain = kind == ContactState::ForceWeights::domain;
  return static_cast<int>(std::ceil((KernelTraits<K>::kNodes + domain) * g.h.maxCoeff() / spacing));
}

/// The ghost rows' sums for a wall across grid axis `axis` whose normal points to `side` (+1
/// or -1), at contact coordinate `at` along that axis (ghost_weights): `along[k]` is the sum
/// over the rows of the force weights at the stencil's node k along the axis.
template <Kernel K>
void ghost_rows(Real at, int axis, Real side, Real spacing, ContactState::ForceWeights kind,
                const Grid& g, Real* along) {
  using ForceWeights = ContactState::ForceWeights;
  const bool mls = kind == ForceWeights::mls, domain = kind == ForceWeights::domain;
  constexpr int N = KernelTraits<K>::kNodes;
  std::fill(along, along + N, Real(0));
  const int rows = ghost_row_count<K>(spacing, kind, g);
  const Real h = g.h[axis], inv_h = g.inv_h[axis];
  const Real inv_d = KernelTraits<K>::kInvDScale * inv_h * inv_h;
  const int first = KernelTraits<K>::base((at - g.origin[axis]) * inv_h);
  for (int r = 0; r < rows; ++r) {
    const Real xg = at - (r + Real(0.5)) * spacing * side;
    const Real fx = (xg - g.origin[axis]) * inv_h;
    if (domain) {
      const DomainAxis d = domain_axis(fx, std::min(spacing * inv_h, Real(1)), h);
      for (int k = 0; k < 4; ++k) {
        const int rel = d.base + k - first;
        if (rel >= 0 && rel < N) along[rel] += spacing * side * d.s[k];
      }
      continue;
    }
    const int base = KernelTraits<K>::base(fx);
    Real w[N], dw[N];
    KernelTraits<K>::weights(fx - base, w, dw);
    for (int k = 0; k < N; ++k) {
      const int rel = base + k - first;
      if (rel < 0 || rel >= N) continue;
      const Real to_node = g.origin[axis] + (base + k) * h - xg;
      along[rel] += spacing * side * (mls ? w[k] * inv_d * to_node : dw[k] * inv_h);
    }
  }
}

/// The weights with which contact c's impulse enters the N^3 nodes of its contact point's
/// stencil `s`: the force that a continuation of the body behind the wall, rows of particles
/// of the contact's spacing under uniform pressure, would put on each node, along the normal
/// (a mirror image, as ghost particles make walls in SPH: Adami, Hu and Adams 2012, "A
/// generalized wall boundary condition for smoothed particle hydrodynamics", JCP 231).
/// Summed with the body's own, that force vanishes at every node, so these are the boundary
/// terms the particles' quadrature of the stress divergence calls for: a body at uniform
/// pressure is in balance node by node wherever the wall lies between the node rows. The
/// force is the stress scatter's: the kernel's gradient, with MLS its D^-1 w (x_i - x)
/// (Hu et al. 2018, eq. 29), or the gradient averaged over each ghost's domain (a cube of
/// the spacing, domain_quadrature.h). With the wall on a node row and APIC these are the contact
/// point's own weights; nodes behind the wall that only a B-spline tail of the body reaches
/// get little or none (docs/accuracy.md, "Walls between the node rows"). `rows`: the
/// contact's ghost_rows if the wall lies across a grid axis and they are known, else null.
template <Kernel K>
void ghost_weights(const Stencil<KernelTraits<K>::kNodes>& s, const Vec3& point, const Vec3& n,
                   Real spacing, ContactState::ForceWeights kind, const Grid& g, const Real* rows,
                   Real* weights) {
  using ForceWeights = ContactState::ForceWeights;
  const bool mls = kind == ForceWeights::mls, domain = kind == ForceWeights::domain;
  constexpr int N = KernelTraits<K>::kNodes;
  std::fill(weights, weights + N * N * N, Real(0));
  int axis;
  if (n.cwiseAbs().maxCoeff(&axis) == 1) {
    // A wall across a grid axis: the ghosts share the contact point's other two coordinates,
    // so each weight is the point's weights across the wall times a sum over the rows along it.
    Real own[N];
    const Real* along = rows;
    if (!along) {
      ghost_rows<K>(point[axis], axis, n[axis], spacing, kind, g, own);
      along = own;
    }
    const int a = (axis + 1) % 3, b = (axis + 2) % 3;
    for (int i = 0; i < N; ++i)
      for (int j = 0; j < N; ++j)
        for (int k = 0; k < N; ++k) {
          const int at[3] = {i, j, k};
          weights[(i * N + j) * N + k] = along[at[axis]] * s.w[a][at[a]] * s.w[b][at[b]];
        }
    return;
  }
  const Vec3 inv_d = KernelTraits<K>::kInvDScale * g.inv_h.cwiseProduct(g.inv_h);
  for (int r = 0, count = ghost_row_count<K>(spacing, kind, g); r < count; ++r) {
    const Vec3 xg = point - (r + Real(0.5)) * spacing * n;
    if (domain) {
      const DomainStencil sd = domain_stencil(xg, spacing * spacing * spacing, g);
      for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j)
          for (int k = 0; k < 4; ++k) {
            const Vec3i rel = sd.base() + Vec3i(i, j, k) - s.base;
            if ((rel.array() < 0).any() || (rel.array() >= N).any()) continue;
            weights[(rel.x() * N + rel.y()) * N + rel.z()] += spacing * sd.gradient(i, j, k).dot(n);
          }
      continue;
    }
    const auto sg = make_stencil<K>(xg, g.origin, g.inv_h);
    for (int i = 0; i < N; ++i)
      for (int j = 0; j < N; ++j)
        for (int k = 0; k < N; ++k) {
          const Vec3i node = sg.base + Vec3i(i, j, k);
          const Vec3i rel = node - s.base;
          if ((rel.array() < 0).any() || (rel.array() >= N).any()) continue;
          const Vec3 grad =
              mls ? Vec3(sg.weight(i, j, k) *
                         inv_d.cwiseProduct(g.position(node.x(), node.y(), node.z()) - xg))
                  : sg.gradient(i, j, k);
          weights[(rel.x() * N + rel.y()) * N + rel.z()] += spacing * grad.dot(n);
        }
  }
}

/// Keeps only the contacts that act (`acts`; st's arrays and the stencil weights compacted in
/// order) and numbers the grid nodes of their stencils (grid storage indices `storage_index`
/// of each contact's S nodes, kNoNode for none) compactly in first-touch order, node 0 being
/// none; then takes each node's velocity, inverse mass and key, in parallel over the nodes.
void keep_acting_contacts(const std::vector<char>& acts, const std::size_t* storage_index,
                          const Grid& g, ContactState& st) {
  const int S = st.stencil;
  if (st.compact.size() < g.mass.size()) st.compact.resize(g.mass.size(), -1);
  st.storage.assign(1, kNoNode);  // compact node 0: none, weight 0, no mass
  resize_kept(st.nodes, st.weights.size());
  std::size_t kept = 0;
  const std::size_t* last = nullptr;  // the last kept contact's storage indices
  for (std::size_t c = 0; c < st.size(); ++c) {
    if (!acts[c]) continue;
    copy_contact(st, c, kept);
    const std::size_t* here = &storage_index[c * S];
    if (kept != c) std::copy_n(&st.weights[c * S], S, &st.weights[kept * S]);
    // Most contacts share the stencil of the one before them.
    if (last && std::equal(here, here + S, last))
      std::copy_n(&st.nodes[(kept - 1) * S], S, &st.nodes[kept * S]);
    else
      for (int t = 0; t < S; ++t) {
        const std::size_t at = here[t];
        std::uint32_t node = 0;
        if (at != kNoNode) {
          std::int32_t& id = st.compact[at];
          if (id < 0) {
            id = static_cast<std::int32_t>(st.storage.size());
            st.storage.push_back(at);
          }
          node = static_cast<std::uint32_t>(id);
        }
        st.nodes[kept * S + t] = node;
      }
    last = here;
    ++kept;
  }
  resize_contacts(st, kept);
  st.weights.resize(kept * S);
  st.nodes.resize(kept * S);
  const std::ptrdiff_t nn = static_cast<std::ptrdiff_t>(st.storage.size());
  st.node_velocity.resize(nn);
  st.node_inv_mass.resize(nn);
  st.node_key.resize(nn);
  constexpr int E = Grid::kBlockEdge;
  st.node_velocity[0] = Vec3::Zero();
  st.node_inv_mass[0] = 0;
  st.node_key[0] = ~std::uint64_t{0};
#pragma omp parallel for schedule(static) if (nn >= kParallelMinItems)
  for (std::ptrdiff_t i = 1; i < nn; ++i) {
    const std::size_t at = st.storage[i];
    st.compact[at] = -1;
    st.node_velocity[i] = g.velocity[at];
    st.node_inv_mass[i] = g.mass[at] > 0 ? 1 / g.mass[at] : 0;
    const Vec3i first = g.block_first[at / Grid::kBlockNodes];
    const int o = static_cast<int>(at % Grid::kBlockNodes);
    const Vec3i node = first + Vec3i(o / (E * E), o / E % E, o % E);
    st.node_key[i] = (static_cast<std::uint64_t>(node.x()) * g.nodes.y() + node.y()) *
                         static_cast<std::uint64_t>(g.nodes.z()) +
                     node.z();
  }
}

/// The ghost rows (ghost_rows) the contacts on walls across a grid axis share: one set per
/// wall coordinate, side and spacing, which find_contacts gives such a wall's contact points
/// exactly. Most scenes have a few; past kMost, further ones are found per contact.
template <Kernel K>
struct SharedGhostRows {
  static constexpr int N = KernelTraits<K>::kNodes;
  static constexpr std::size_t kMost = 64;  ///< The most sets kept.
  /// One set of rows and what it is for.
  struct Entry {
    int axis;
    Real side, at, spacing;
    Real along[N];
  };
  std::vector<Entry> entries;  ///< The sets.
  std::vector<int> of;         ///< Per contact, its set, or -1.

  /// The sets of the contacts of `st`, whose particles have the per-object `spacing`.
  SharedGhostRows(const ContactState& st, const Particles& p, const std::vector<Real>& spacing,
                  const Grid& g)
      : of(st.size(), -1) {
    for (std::size_t c = 0; c < st.size(); ++c) {
      int axis;
      const Vec3& n = st.normal[c];
      if (n.cwiseAbs().maxCoeff(&axis) != 1) continue;
      const Real side = n[axis], at = st.point[c][axis];
      const Real sp = spacing[p.object[st.particle[c]]];
      const auto is = [&](std::size_t e) {
        return entries[e].axis == axis && entries[e].side == side && entries[e].at == at &&
               entries[e].spacing == sp;
      };
      // Most contacts share the set of the one before them (they come wall by wall).
      std::size_t e = c > 0 && of[c - 1] >= 0 && is(of[c - 1]) ? of[c - 1] : 0;
      while (e < entries.size() && !is(e)) ++e;
      if (e == entries.size()) {
        if (e == kMost) continue;
        entries.push_back({axis, side, at, sp, {}});
        ghost_rows<K>(at, axis, side, sp, st.force_weights, g, entries.back().along);
      }
      of[c] = static_cast<int>(e);
    }
  }
  /// Contact c's rows, or null.
  const Real* rows(std::size_t c) const { return of[c] < 0 ? nullptr : entries[of[c]].along; }
};

/// The contacts' stencils (weights, grid storage indices), then compact node indices in
/// first-touch order with each node's velocity, inverse mass and key. The contacts come from
/// the search, whose StencilClosing has dropped those that cannot close their gap; the ones
/// whose interpolated velocity does not close it are dropped here.
template <Kernel K>
void gather_stencils(Real dt, const Particles& p, const Grid& g, ContactState& st) {
  constexpr int N = KernelTraits<K>::kNodes, S = N * N * N;
  const std::size_t nc = st.size();
  const std::ptrdiff_t sn = static_cast<std::ptrdiff_t>(nc);
  // Every contact's stencil is written: the scratch is only grown, never cleared.
  resize_kept(st.stencil_storage, nc * S);
  std::size_t* const storage_index = st.stencil_storage.data();
  std::vector<char> acts(nc, 0);
  st.stencil = S;
  resize_kept(st.weights, nc * S);
  // Each object's particle spacing, for the ghost rows.
  std::vector<Real> spacing(p.object_volume0.size());
  for (std::size_t o = 0; o < spacing.size(); ++o) spacing[o] = std::cbrt(p.object_volume0[o]);
  const SharedGhostRows<K> shared(st, p, spacing, g);
  // The stencil of the contact point, on the wall: the velocity there is the contact's, so a
  // ball rolls on the wall, not on its particles' centres; its impulse enters with the ghost
  // weights. Nodes without mass take no part, and the weights of the others are scaled to
  // sum to one.
#pragma omp parallel if (sn * S >= kParallelMinItems)
  {
    // The last stencil's nodes with mass and their velocities: the contacts come wall by wall
    // in cell order, so most share the one before them (one copy per thread).
    Vec3i last = Vec3i::Constant(std::numeric_limits<int>::min());
    std::array<std::size_t, S> nodes;
    std::array<Vec3, S> velocity;
    velocity.fill(Vec3::Zero());
#pragma omp for schedule(static)
    for (std::ptrdiff_t c = 0; c < sn; ++c) {
      const auto s = make_stencil<K>(st.point[c], g.origin, g.inv_h);
      if (s.base != last) {
        last = s.base;
        g.stencil_indices<N, true>(s.base, nodes.data());  // kNoStorage is kNoNode
        for (int t = 0; t < S; ++t) {
          if (nodes[t] != kNoNode && !(g.mass[nodes[t]] > 0)) nodes[t] = kNoNode;
          velocity[t] = nodes[t] == kNoNode ? Vec3::Zero() : g.velocity[nodes[t]];
        }
      }
      std::copy_n(nodes.begin(), S, &storage_index[c * S]);
      Real* w = &st.weights[c * S];
      ghost_weights<K>(s, st.point[c], st.normal[c], spacing[p.object[st.particle[c]]],
                       st.force_weights, g, shared.rows(c), w);
      Real sum = 0;
      for (int t = 0; t < S; ++t) {
        w[t] = nodes[t] == kNoNode ? 0 : std::max(w[t], Real(0));
        sum += w[t];
      }
      for (int t = 0; t < S; ++t) w[t] = sum > 0 ? w[t] / sum : 0;
      // It acts if touching, or closing its gap within the substep at the velocity
      // interpolated now (the solve's impulses only push particles away).
      const auto closing = [&] {
        Vec3 u = Vec3::Zero();
        for (int t = 0; t < S; ++t) u += w[t] * velocity[t];
        return (u - st.wall_velocity[c]).dot(st.normal[c]) < -st.gap[c] / dt;
      };
      acts[c] = sum > 0 && (st.gap[c] <= 0 || closing());
    }
  }
  keep_acting_contacts(acts, storage_index, g, st);
}

/// The stencil entries of the contacts of `st` by node: node i's are contact[first[i]] to
/// contact[first[i + 1] - 1] with their weights, in contact order (node 0, none, has none).
/// Each node then sums its own contacts' impulses: in parallel over the nodes, and in
/// contact order whatever the thread count.
struct NodeEntries {
  std::vector<std::uint32_t> first;    ///< Per compact node, its first entry; and one more.
  std::vector<std::uint32_t> contact;  ///< Each entry's contact.
  std::vector<Real> weight;            ///< Each entry's stencil weight.

  /// The entries of the contacts of `st`.
  explicit NodeEntries(const ContactState& st) : first(st.node_velocity.size() + 1, 0) {
    const int S = st.stencil;
    const std::size_t ne = st.nodes.size();
    for (std::size_t e = 0; e < ne; ++e)
      if (st.nodes[e] != 0) ++first[st.nodes[e] + 1];
    for (std::size_t i = 1; i < first.size(); ++i) first[i] += first[i - 1];
    contact.resize(first.back());
    weight.resize(first.back());
    std::vector<std::uint32_t> fill(first.begin(), first.end() - 1);
    for (std::size_t c = 0; c < st.size(); ++c)
      for (int t = 0; t < S; ++t) {
        const std::uint32_t i = st.nodes[c * S + t];
        if (i == 0) continue;
        contact[fill[i]] = static_cast<std::uint32_t>(c);
        weight[fill[i]++] = st.weights[c * S + t];
      }
  }
};

/// st.inv_k: the inverse row sums of W M^-1 W^T (the stencils by node: `by_node`). A contact's
/// step is its violation over its row sum, so the part of the impulses that is the same at
/// every contact, a body pressing on the wall as a whole, is found in the first iteration, and
/// no mode is overshot. `par`: in parallel.
void row_sum_inverses(const NodeEntries& by_node, bool par, ContactState& st) {
  const int S = st.stencil;
  const std::ptrdiff_t sn = static_cast<std::ptrdiff_t>(st.size());
  const std::ptrdiff_t nn = static_cast<std::ptrdiff_t>(st.node_velocity.size());
  const std::vector<Real>& inv_m = st.node_inv_mass;
  std::vector<Real> share(nn, 0);
#pragma omp parallel for schedule(static) if (par)
  for (std::ptrdiff_t i = 1; i < nn; ++i)
    for (std::uint32_t k = by_node.first[i]; k < by_node.first[i + 1]; ++k)
      share[i] += by_node.weight[k];
#pragma omp parallel for schedule(static) if (par)
  for (std::ptrdiff_t c = 0; c < sn; ++c) {
    Real k = 0;
    for (int t = 0; t < S; ++t) {
      const std::uint32_t i = st.nodes[c * S + t];
      const Real w = st.weights[c * S + t];
      k += w * share[i] * inv_m[i];
    }
    st.inv_k[c] = k > 0 ? 1 / k : 0;
  }
}

/// Reorders `v`, `stride` entries per contact: entry group c takes group order[c].
template <class T>
void permute(const std::vector<std::uint32_t>& order, int stride, std::vector<T>& v) {
  std::vector<T> from(v);
  for (std::size_t c = 0; c < order.size(); ++c)
    std::copy_n(&from[order[c] * stride], stride, &v[c * stride]);
}

/// Puts the contacts of `st` in order of patch and particle id. The order they are found in
/// depends on the particles' places in memory and, with ranks, on which rank holds them, and
/// the solve's sums follow it: sorted, one and two ranks add the same impulses in the same
/// order (with the warm start's memory kept per particle and wall, the pool at rest drifted
/// apart between one and two ranks otherwise; docs/accuracy.md). The stencils stay where they
/// are: returns where each sorted contact's is (sorted contact c's is at order[c]), or nothing
/// if the contacts were in order already.
std::vector<std::uint32_t> sort_contacts(ContactState& st) {
  // Each contact's patch and id as one key, patch * (largest id + 1) + id (a particle has one
  // contact per patch, so the keys differ).
  const std::size_t nc = st.size();
  if (nc == 0) return {};
  const std::uint64_t ids = std::uint64_t{*std::max_element(st.id.begin(), st.id.end())} + 1;
  std::vector<std::uint64_t> keys(nc);
  for (std::size_t c = 0; c < nc; ++c) keys[c] = st.patch[c] * ids + st.id[c];
  if (std::is_sorted(keys.begin(), keys.end())) return {};
  // Radix passes: time in proportion to the contacts (std::sort took 2.8 times as long on
  // two_cubes' contacts, docs/performance.md).
  std::vector<std::uint32_t> order, scratch;
  radix_order(
      nc, static_cast<int>(std::bit_width(*std::max_element(keys.begin(), keys.end()))),
      [&](std::uint32_t c) { return keys[c]; }, order, scratch);
  for (auto* v : {&st.particle, &st.id, &st.patch}) permute(order, 1, *v);
  for (auto* v : {&st.point, &st.normal, &st.wall_velocity}) permute(order, 1, *v);
  permute(order, 1, st.gap);
  permute(order, 1, st.boundary);
  permute(order, 1, st.friction);
  return order;
}

/// The contacts as they were before merge_shared_stencils (in patch and particle id order),
/// and the merged contact each went into.
struct Members {
  std::vector<std::uint32_t> id;     ///< Particle id of each.
  std::vector<std::uint32_t> patch;  ///< Its patch.
  std::vector<std::uint32_t> group;  ///< Its merged contact.
};

/// Merges the contacts of `st` that share a patch and whose stencils reach the same nodes
/// (their contact points lie in one stencil base cell), touching or closing alike, into one
/// contact that stands for all of them (st.count): its weights are their weights' mean, its
/// normal and wall velocity their means, its gap their least. The grid resolves the traction
/// only to its nodes, and W M^-1 W^T is singular where more contacts than nodes share a
/// stencil, so the merged set poses the same condition on the node velocities as the
/// particles' own (at uniform pressure their impulses are equal, and the mean weights put the
/// same force on each node), with one unknown per stencil and patch: a body squashed flat on
/// a floor, its particles by the hundred per cell, costs as much as one that rests on it.
/// Contacts keep their first-found order. Their stencils are read at `order` (sort_contacts)
/// and left in contact order. Returns each merged contact's particles.
Members merge_shared_stencils(const std::vector<std::uint32_t>& order, ContactState& st) {
  const int S = st.stencil;
  const std::size_t nc = st.size();
  const auto from = [&](std::size_t c) { return order.empty() ? c : std::size_t{order[c]}; };
  // A stencil is named by its first node with mass and that node's place in it: contacts
  // with one stencil base reach the same nodes, and different bases give different names.
  struct Key {
    std::uint64_t node;  ///< node_key of the stencil's first node with mass.
    std::uint32_t place, patch;
    bool touching;
    bool operator==(const Key&) const = default;
  };
  struct Hash {
    std::size_t operator()(const Key& k) const {
      return splitmix64(k.node ^
                        splitmix64((std::uint64_t{k.patch} << 32 | k.place) * 2 + k.touching));
    }
  };
  // The groups in an open-addressed table (linear probing) of at least twice their number.
  const std::size_t mask = std::bit_ceil(2 * nc + 1) - 1;
  constexpr std::uint32_t kEmpty = ~std::uint32_t{0};
  std::vector<std::uint32_t> table(mask + 1, kEmpty), leader;
  std::vector<Key> keys;
  Members m{st.id, st.patch, std::vector<std::uint32_t>(nc)};
  for (std::size_t c = 0; c < nc; ++c) {
    std::uint32_t t = 0;
    const std::size_t at = from(c) * S;
    while (t + 1 < static_cast<std::uint32_t>(S) && st.nodes[at + t] == 0) ++t;
    const Key k{st.node_key[st.nodes[at + t]], t, st.patch[c], st.gap[c] <= 0};
    std::size_t h = Hash{}(k);
    h &= mask;
    while (table[h] != kEmpty && !(keys[table[h]] == k)) h = (h + 1) & mask;
    if (table[h] == kEmpty) {
      table[h] = static_cast<std::uint32_t>(leader.size());
      leader.push_back(static_cast<std::uint32_t>(c));
      keys.push_back(k);
    }
    m.group[c] = table[h];
  }
  const std::size_t ng = leader.size();
  if (ng == nc) {
    st.count.assign(nc, 1);
    if (!order.empty()) {
      permute(order, S, st.nodes);
      permute(order, S, st.weights);
    }
    return m;
  }
  // Each group's members in contact order, so that the groups are summed in parallel and
  // each in that order, whatever the thread count.
  std::vector<std::uint32_t> first(ng + 1, 0), member(nc);
  for (std::size_t c = 0; c < nc; ++c) ++first[m.group[c] + 1];
  for (std::size_t g = 0; g < ng; ++g) first[g + 1] += first[g];
  {
    std::vector<std::uint32_t> next(first.begin(), first.end() - 1);
    for (std::size_t c = 0; c < nc; ++c) member[next[m.group[c]]++] = static_cast<std::uint32_t>(c);
  }
  std::vector<Vec3> normal(ng), wall_velocity(ng);
  std::vector<Real> gap(ng);
  resize_kept(st.spare_weights, ng * S);  // every entry written below
  resize_kept(st.spare_nodes, ng * S);
  st.count.resize(ng);
  const std::ptrdiff_t sg = static_cast<std::ptrdiff_t>(ng);
#pragma omp parallel for schedule(static) if (static_cast<long>(nc) * S >= kParallelMinItems)
  for (std::ptrdiff_t g = 0; g < sg; ++g) {
    Vec3 nsum = Vec3::Zero(), vsum = Vec3::Zero();
    Real least = std::numeric_limits<Real>::max();
    Real* w = &st.spare_weights[g * S];
    std::fill(w, w + S, Real(0));
    for (std::uint32_t k = first[g]; k < first[g + 1]; ++k) {
      const std::size_t c = member[k];
      nsum += st.normal[c];
      vsum += st.wall_velocity[c];
      least = std::min(least, st.gap[c]);
      const Real* from_w = &st.weights[from(c) * S];
      for (int t = 0; t < S; ++t) w[t] += from_w[t];
    }
    const std::size_t c = leader[g];
    const Real n = static_cast<Real>(first[g + 1] - first[g]);
    const Real length = nsum.norm();
    normal[g] = length > 0 ? Vec3(nsum / length) : st.normal[c];
    wall_velocity[g] = vsum / n;
    gap[g] = least;
    st.count[g] = n;
    for (int t = 0; t < S; ++t) {
      w[t] /= n;
      st.spare_nodes[g * S + t] = st.nodes[from(c) * S + t];
    }
  }
  // In place: a group's leader is never before it.
  for (std::size_t g = 0; g < ng; ++g) copy_contact(st, leader[g], g);
  resize_contacts(st, ng);
  st.normal = std::move(normal);
  st.wall_velocity = std::move(wall_velocity);
  st.gap = std::move(gap);
  st.weights.assign(st.spare_weights.begin(), st.spare_weights.end());  // no new pages
  st.nodes.assign(st.spare_nodes.begin(), st.spare_nodes.end());
  return m;
}

/// Starts each contact of `st` from its particles' (`members`) normal impulses on the same wall
/// in the last substep (`memory`, in the same order: one pass over both), applied to the node
/// velocities in contact order. Returns the moving walls' work of those impulses.
Real warm_start(Real dt, const ContactMemory& memory, const Members& members, ContactState& st) {
  const int S = st.stencil;
  Real work = 0;
  st.normal_impulse.assign(st.size(), 0);
  if (memory.dt > 0) {
    std::size_t k = 0;
    const std::size_t kept = memory.ids.size();
    for (std::size_t c = 0; c < members.id.size(); ++c) {
      const std::uint64_t want = contact_key(members.patch[c], members.id[c]);
      while (k < kept && contact_key(memory.patches[k], memory.ids[k]) < want) ++k;
      if (k < kept && contact_key(memory.patches[k], memory.ids[k]) == want)
        st.normal_impulse[members.group[c]] += memory.impulses[k] * dt / memory.dt;  // same force
    }
  }
  for (std::size_t c = 0; c < st.size(); ++c) {
    const Real start = st.normal_impulse[c];
    if (start == 0) continue;
    work += start * st.normal[c].dot(st.wall_velocity[c]);
    for (int t = 0; t < S; ++t) {
      const std::uint32_t i = st.nodes[c * S + t];
      st.node_velocity[i] += st.weights[c * S + t] * start * st.node_inv_mass[i] * st.normal[c];
    }
  }
  return work;
}

/// `f` shortened to at most `cap` long.
Vec3 within(Real cap, const Vec3& f) {
  // Well within the cap (a sticking node) it is f, without the square root's wait: below
  // cap^2 (1 - 1e-15), rounded, |f| rounds to at most cap, so the answer is the same.
  const Real s = f.squaredNorm();
  if (s < cap * cap * (1 - Real(1e-15))) return f;
  const Real t = std::sqrt(s);
  return t > cap ? (t > 0 ? Vec3(f * (cap / t)) : Vec3::Zero()) : f;
}

/// The weights of Chebyshev's semi-iteration (Wang 2015, contact.h) for Jacobi steps of spectral
/// radius `rho`: each iterate is omega (step - earlier) + earlier, from the iterate before the
/// last (`earlier`) and the plain step from the last.
struct Chebyshev {
  Real rho;        ///< The spectral radius assumed (0: omega is always 1, plain steps).
  Real omega = 1;  ///< The weight of the current iteration.

  /// The weight of iteration `it` (called once per iteration, in order).
  Real next(int it) {
    omega = it == 0 ? 1 : it == 1 ? 2 / (2 - rho * rho) : 4 / (4 - rho * rho * omega);
    return omega;
  }
};

/// What one contact's nodes take of an iteration besides its friction request
/// (ContactSteps::ask): its normal (and held) impulse change and, if it rubs (friction, not
/// held), its share of its patch's capacity.
struct ToNodes {
  Vec3 push = Vec3::Zero();  ///< Change of the normal impulse along the normal, plus a held
                             ///< contact's tangential change, N s.
  /// Its friction request (ContactSteps::ask) if it rubs, else zero, N s: the nodes add every
  /// entry's without a branch, and a zero leaves their sums' bits as they were (the sums start
  /// at +0, which adding a zero of either sign keeps).
  Vec3 ask = Vec3::Zero();
  Real share = 0;            ///< Share of the patch's friction capacity if it rubs, else 0, N s.
  bool rubs = false;         ///< Whether it rubs.
};

/// Contacts whose velocities interpolate_velocities interpolates side by side.
constexpr int kInterleaved = 4;

/// The velocities at contacts [first, first + m) of `st` (m <= kInterleaved), each interpolated
/// from its stencil's nodes in stencil order. The contacts' sums run side by side: each sum is
/// a chain of dependent additions, and interleaved they overlap (the same additions in the
/// same order as one contact at a time).
void interpolate_velocities(const ContactState& st, std::ptrdiff_t first, int m, Vec3* u) {
  const int S = st.stencil;
  const Real* w = &st.weights[first * S];
  const std::uint32_t* node = &st.nodes[first * S];
  for (int j = 0; j < kInterleaved; ++j) u[j] = Vec3::Zero();
  if (m == kInterleaved) {
    for (int t = 0; t < S; ++t)
      for (int j = 0; j < kInterleaved; ++j)
        u[j] += w[j * S + t] * st.node_velocity[node[j * S + t]];
    return;
  }
  for (int j = 0; j < m; ++j)
    for (int t = 0; t < S; ++t) u[j] += w[j * S + t] * st.node_velocity[node[j * S + t]];
}

/// One iteration's requests of every contact, and what Chebyshev's acceleration keeps of the
/// iterations before: each contact's normal impulse an iteration before, and a held contact's
/// accumulated tangential impulse now and an iteration before (the nodes keep their
/// friction's, NodeFriction::earlier).
struct ContactSteps {
  std::vector<Real> ln;            ///< Normal impulses after this iteration, N s.
  std::vector<Vec3> ask;           ///< Tangential requests (held: impulse changes), N s.
  std::vector<Real> dn;            ///< This iteration's change of the normal impulses, N s.
  /// What each contact's nodes take of this iteration (ToNodes), side by side.
  std::vector<ToNodes> to_nodes;
  std::vector<Real> earlier;       ///< Normal impulses an iteration before, N s.
  std::vector<Vec3> held_impulse;  ///< A held contact's tangential impulse, N s.
  std::vector<Vec3> held_earlier;  ///< The same an iteration before, N s.
  std::vector<Real> load;          ///< Per patch, mu times its rubbing contacts' normal impulses.
  std::vector<Real> rubbers;       ///< Per patch, the particles its rubbing contacts stand for.

  /// Nothing asked yet, from the warm-started impulses of `st`.
  explicit ContactSteps(const ContactState& st)
      : ln(st.size()),
        ask(st.size()),
        dn(st.size()),
        to_nodes(st.size()),
        earlier(st.normal_impulse),
        held_impulse(st.size(), Vec3::Zero()),
        held_earlier(st.size(), Vec3::Zero()),
        load(st.patches),
        rubbers(st.patches) {
    for (std::size_t c = 0; c < st.size(); ++c) to_nodes[c].rubs = !held(st, c) && rubs(st, c);
  }

  /// Each contact's projected Jacobi step from the velocity interpolated at its contact point,
  /// extrapolated by the Chebyshev weight `omega` from the iterate before the last and
  /// projected again; the change is taken into st.normal_impulse and `to_nodes`. Sets
  /// `residual` to the largest violation before the step (violation); returns the largest
  /// impulse change or request.
  Real take(ContactState& st, Real dt, Real omega, bool par, Real& residual) {
    const std::ptrdiff_t sn = static_cast<std::ptrdiff_t>(st.size());
    const std::ptrdiff_t sets = (sn + kInterleaved - 1) / kInterleaved;
    using Largest = std::array<Real, 2>;  // the largest change or request, the worst violation
    const Largest out = for_ranges(
        sets, par, Largest{0, 0},
        [&](std::ptrdiff_t from, std::ptrdiff_t to) {
          Real largest = 0, worst = 0;
          for (std::ptrdiff_t set = from; set < to; ++set) {
            const std::ptrdiff_t first = set * kInterleaved;
            const int m = static_cast<int>(std::min<std::ptrdiff_t>(kInterleaved, sn - first));
            Vec3 at[kInterleaved];
            interpolate_velocities(st, first, m, at);
            for (int j = 0; j < m; ++j) take_one(st, first + j, at[j], dt, omega, largest, worst);
          }
          return Largest{largest, worst};
        },
        [](const Largest& a, const Largest& b) {
          return Largest{std::max(a[0], b[0]), std::max(a[1], b[1])};
        });
    residual = out[1];
    return out[0];
  }

  /// take() at contact c, from the velocity `u` interpolated at its point.
  void take_one(ContactState& st, std::ptrdiff_t c, const Vec3& u, Real dt, Real omega,
                Real& largest, Real& worst) {
    worst = std::max(worst, violation(st, c, u));
    const Real step = normal_impulse(st, c, u, dt);
    const Real extrapolated = omega * (step - earlier[c]) + earlier[c];
    const bool hold = held(st, c);
    ln[c] = hold ? extrapolated : std::max(extrapolated, Real(0));
    earlier[c] = st.normal_impulse[c];
    const Vec3& n = st.normal[c];
    const Vec3 ur = u - st.wall_velocity[c];
    ask[c] = rubs(st, c) ? Vec3(-(ur - ur.dot(n) * n) * st.inv_k[c]) : Vec3::Zero();
    if (hold) {  // its tangential impulse, accumulated, extrapolated alike
      const Vec3 t = omega * (held_impulse[c] + ask[c] - held_earlier[c]) + held_earlier[c];
      held_earlier[c] = held_impulse[c];
      ask[c] = t - held_impulse[c];
      held_impulse[c] = t;
    }
    dn[c] = ln[c] - st.normal_impulse[c];
    largest = std::max({largest, std::abs(dn[c]), ask[c].norm()});
    to_nodes[c].push = dn[c] * n + (hold ? ask[c] : Vec3::Zero());
    if (to_nodes[c].rubs) to_nodes[c].ask = ask[c];
    st.normal_impulse[c] = ln[c];
  }

  /// The moving walls' work of this iteration's normal and held impulses, in contact order
  /// (after take()).
  Real work(const ContactState& st) const {
    Real sum = 0;
    for (std::size_t c = 0; c < st.size(); ++c) {
      sum += dn[c] * st.normal[c].dot(st.wall_velocity[c]);
      if (held(st, c)) sum += ask[c].dot(st.wall_velocity[c]);
    }
    return sum;
  }

  /// Each rubbing contact's share of its patch's friction capacity: mu times the normal
  /// impulses of the patch's rubbing contacts, spread evenly over the particles they stand for.
  void share_capacity(const ContactState& st) {
    std::fill(load.begin(), load.end(), 0);
    std::fill(rubbers.begin(), rubbers.end(), 0);
    for (std::size_t c = 0; c < st.size(); ++c)
      if (to_nodes[c].rubs) {
        load[st.patch[c]] += st.friction[c] * std::max(ln[c], Real(0));
        rubbers[st.patch[c]] += st.count[c];
      }
    for (std::size_t c = 0; c < st.size(); ++c)
      if (to_nodes[c].rubs)
        to_nodes[c].share = st.count[c] * load[st.patch[c]] / rubbers[st.patch[c]];
  }
};

/// The friction at the nodes over one solve: each node's accumulated friction impulse, and the
/// weights and weighted wall velocities of its rubbing contacts (which contacts rub does not
/// change within a substep).
struct NodeFriction {
  std::vector<Vec3> friction;   ///< Accumulated friction impulse, N s.
  std::vector<Vec3> wall_v;     ///< Sum of the rubbing contacts' weights times wall velocities.
  std::vector<Real> rubbing;    ///< Sum of the rubbing contacts' weights.
  std::vector<Vec3> earlier;    ///< The accumulated friction impulse an iteration before.
  std::vector<Real> node_work;  ///< The moving walls' work of each node's last friction change.

  /// No friction yet, at the nodes of `st` (their stencil entries `by_node`; which contacts
  /// rub: `contacts`).
  NodeFriction(const ContactState& st, const NodeEntries& by_node,
               const std::vector<ToNodes>& contacts, bool par)
      : friction(st.node_velocity.size(), Vec3::Zero()),
        wall_v(st.node_velocity.size(), Vec3::Zero()),
        rubbing(st.node_velocity.size(), 0),
        earlier(st.node_velocity.size(), Vec3::Zero()),
        node_work(st.node_velocity.size(), 0) {
    const std::ptrdiff_t nn = static_cast<std::ptrdiff_t>(st.node_velocity.size());
#pragma omp parallel for schedule(static) if (par)
    for (std::ptrdiff_t i = 1; i < nn; ++i)
      for (std::uint32_t k = by_node.first[i]; k < by_node.first[i + 1]; ++k) {
        const std::uint32_t c = by_node.contact[k];
        if (!contacts[c].rubs) continue;
        const Real w = st.count[c] * by_node.weight[k];
        wall_v[i] += w * st.wall_velocity[c];
        rubbing[i] += w;
      }
  }

  /// Sums at each node of `st` what its contacts (`by_node`) give it this iteration (`steps`'
  /// to_nodes and ask: impulse changes, and the friction requests and capacity shares of those
  /// that rub), keeps the friction within its capacity, extrapolates it by the Chebyshev weight
  /// `omega` (and keeps it within its capacity again), and changes the node velocities by the
  /// impulses; adds the moving walls' work of the friction to `work`, in node order (`moving`: any
  /// wall moves). Returns the largest squared velocity change.
  Real apply(const NodeEntries& by_node, const ContactSteps& steps, bool par, bool moving,
             Real omega, ContactState& st, Real& work) {
    const std::ptrdiff_t nn = static_cast<std::ptrdiff_t>(st.node_velocity.size());
    const auto nodes = [&](std::ptrdiff_t from, std::ptrdiff_t to) {
      Real change = 0;  // nodes from + 1 to `to` (node 0 is none)
      for (std::ptrdiff_t i = from + 1; i <= to; ++i)
        change = std::max(change, apply_at(i, by_node, steps, moving, omega, st));
      return change;
    };
    const Real change =
        for_ranges(nn - 1, par, Real(0), nodes, [](Real a, Real b) { return std::max(a, b); });
    if (moving) {
      Real sum = 0;
      for (std::ptrdiff_t i = 1; i < nn; ++i)
        if (rubbing[i] > 0) sum += node_work[i];
      work += sum;
    }
    return change;
  }

  /// apply() at node i: returns its squared velocity change.
  Real apply_at(std::ptrdiff_t i, const NodeEntries& by_node, const ContactSteps& steps,
                bool moving, Real omega, ContactState& st) {
    Vec3 step = Vec3::Zero(), trial = Vec3::Zero();
    Real cap = 0;
    for (std::uint32_t k = by_node.first[i]; k < by_node.first[i + 1]; ++k) {
      const std::uint32_t c = by_node.contact[k];
      const Real w = by_node.weight[k];
      const ToNodes& from = steps.to_nodes[c];
      step += w * from.push;
      trial += w * from.ask;
      cap += w * from.share;
    }
    const Vec3 f =
        within(cap, omega * (within(cap, friction[i] + trial) - earlier[i]) + earlier[i]);
    earlier[i] = friction[i];
    const Vec3 df = f - friction[i];
    friction[i] = f;
    if (moving && rubbing[i] > 0) node_work[i] = df.dot(wall_v[i]) / rubbing[i];
    const Vec3 dv = (step + df) * st.node_inv_mass[i];
    st.node_velocity[i] += dv;
    return dv.squaredNorm();
  }
};

/// Keeps each particle's equal share of its merged contact's (`members`) normal impulse in
/// `memory`, for the next substep's warm start.
void keep_impulses(const Members& members, const ContactState& st, Real dt, ContactMemory& memory) {
  std::vector<Real> impulse(members.id.size());
  for (std::size_t c = 0; c < impulse.size(); ++c)
    impulse[c] = st.normal_impulse[members.group[c]] / st.count[members.group[c]];
  memory.keep(members.id, members.patch, impulse, dt);
}

}  // namespace

Real solve_contact(const ContactSettings& settings, Real dt, ContactState& st,
                   ContactMemory& memory) {
  const Members members = merge_shared_stencils(sort_contacts(st), st);
  const int S = st.stencil;
  const std::size_t nc = st.size();
  const std::ptrdiff_t sn = static_cast<std::ptrdiff_t>(nc);
  st.inv_k.assign(nc, 0);
  // Two parallel loops an iteration, each a fork and a barrier.
  const bool par = sn * S >= kParallelMinItems;
  Real work = warm_start(dt, memory, members, st);
  const NodeEntries by_node(st);
  row_sum_inverses(by_node, par, st);
  // Friction is Coulomb's law on the traction, a field over the contact. A particle's own
  // normal impulse is one of many equivalent splits of it among the particles that share
  // nodes (W M^-1 W^T is singular there), so the law is applied at the nodes: each contact
  // asks for the tangential impulse that would stop its contact point sliding, the requests
  // are summed at the nodes, and each node's accumulated friction impulse is kept within its
  // share of the capacity, mu times the normal impulse of every contact of the same wall and
  // object spread evenly over them. Bounds from the particles' own split, or smoothed over
  // their nodes or 4^3-node blocks, let a block on an incline creep (docs/accuracy.md). Sliding
  // everywhere, the total is mu times the total normal impulse exactly. A touching particle
  // of a sticky wall is held directly.
  ContactSteps steps(st);
  NodeFriction friction(st, by_node, steps.to_nodes, par);
  const bool moving = std::any_of(st.wall_velocity.begin(), st.wall_velocity.end(),
                                  [](const Vec3& w) { return w != Vec3::Zero(); });
  Real first_change = 0;
  Chebyshev chebyshev{settings.spectral_radius};
  Real residual = 0;
  int it = 0;
  for (; it < settings.iterations; ++it) {
    const Real omega = chebyshev.next(it);
    const Real largest = steps.take(st, dt, omega, par, residual);
    if (largest == 0) break;
    if (moving) work += steps.work(st);
    steps.share_capacity(st);
    const Real change = friction.apply(by_node, steps, par, moving, omega, st, work);
    // Converged when the velocity changes have fallen by the settings' factor.
    if (it == 0) first_change = change;
    if (change <= settings.tolerance * settings.tolerance * first_change) break;
  }
  memory.stats.solves += 1;
  memory.stats.iterations += std::min(it + 1, settings.iterations);
  memory.stats.residual += residual;
  keep_impulses(members, st, dt, memory);
  return work;
}

void ContactMemory::keep(const std::vector<std::uint32_t>& id,
                         const std::vector<std::uint32_t>& patch, const std::vector<Real>& impulse,
                         Real step) {
  std::vector<std::pair<std::uint64_t, std::uint32_t>> kept;
  for (std::uint32_t c = 0; c < id.size(); ++c)
    if (impulse[c] > 0) kept.push_back({contact_key(patch[c], id[c]), c});
  if (!std::is_sorted(kept.begin(), kept.end())) std::sort(kept.begin(), kept.end());
  ids.resize(kept.size());
  patches.resize(kept.size());
  impulses.resize(kept.size());
  for (std::size_t k = 0; k < kept.size(); ++k) {
    ids[k] = id[kept[k].second];
    patches[k] = patch[kept[k].second];
    impulses[k] = impulse[kept[k].second];
  }
  dt = step;
}

void ContactState::clear() {
  particle.clear();
  id.clear();
  point.clear();
  normal.clear();
  wall_velocity.clear();
  gap.clear();
  boundary.clear();
  friction.clear();
  patch.clear();
  count.clear();
  normal_impulse.clear();
  inv_k.clear();
  nodes.clear();
  weights.clear();
  node_velocity.clear();
  node_inv_mass.clear();
  node_key.clear();
  storage.clear();
}

void write_contact_velocities(const ContactState& st, Grid& g) {
  for (std::size_t i = 1; i < st.storage.size(); ++i)
    if (st.node_inv_mass[i] > 0) g.velocity[st.storage[i]] = st.node_velocity[i];
}

namespace {

/// find_contacts with the kernel K.
template <Kernel K>
void find_contacts_with(const std::vector<WallPlane>& planes,
                        const std::vector<Collider>& colliders, Real time, Real dt,
                        const Particles& p, const Grid& g, const std::vector<IndexRange>* only,
                        const BlockSpeeds* speeds, ContactState& st) {
  const IndexRange everything{0, p.size()};
  const std::span<const IndexRange> search =
      only ? std::span<const IndexRange>(*only) : std::span<const IndexRange>(&everything, 1);
  st.clear();
  const std::vector<Real> radius = half_spacings(p);
  // A contact acts if it is touching or closes its gap within the substep at the velocity
  // interpolated from its nodes (keep_acting_contacts), a mean of node velocities: no farther
  // than dt times the fastest node plus the wall's speed, and never a cell.
  const Real cell = g.h.maxCoeff();
  const GridSpeed speed(g, speeds);
  const Real fastest = speed.speeds.fastest;
  const auto travel = [&](Real wall_speed) { return std::min(cell, dt * (fastest + wall_speed)); };
  const ParticleRadius particle_radius{p, radius, st.rest_depth};
  const Real widest = particle_radius.widest();
  const StencilClosing<K> closes{g, dt, {}};
  // The planes, in one pass over the particles. A plane that coincides with one listed
  // before it (a floor under a box's bottom face, moving alike) is left out: its contacts would
  // pose the same condition twice, and split the normal impulse between the two, so that each
  // wall's friction bound saw only part of it. The first one listed acts.
  std::vector<WallReach> reach;
  std::vector<Vec3> normals, points, velocities;
  for (std::size_t i = 0; i < planes.size(); ++i) {
    const WallPlane& w = planes[i];
    const Vec3 at = w.point + w.offset(time), velocity = w.velocity_at(time + dt);
    const auto same = [&](std::size_t k) {
      return normals[k] == w.normal && velocities[k] == velocity &&
             std::abs((points[k] - at).dot(w.normal)) <= Real(1e-9) * cell;
    };
    std::size_t k = 0;
    while (k < normals.size() && !same(k)) ++k;
    if (k < normals.size()) continue;
    normals.push_back(w.normal);
    points.push_back(at);
    velocities.push_back(velocity);
    reach.push_back(
        {w.boundary, w.friction, travel(velocity.norm()), static_cast<std::uint32_t>(i)});
  }
  // A tile's particles farther from a plane than the widest radius plus the substep's travel at
  // the fastest node near their contact points plus the wall's speed cannot act (the search's
  // own test with GridSpeed::near, over the tile's points at once): they are dropped in the scan.
  // The bound is widened by a part in 10^6, and by a part in 10^9 of the radius, so that
  // rounding never drops a particle the search would keep.
  const auto tile_reach = [&](std::size_t w, const Vec3& lo, const Vec3& hi) {
    const Real closing = speed.near_box(lo, hi, normals[w]) + velocities[w].norm();
    return widest * (1 + Real(1e-9)) + dt * closing * (1 + Real(1e-6));
  };
  find_contacts(
      particle_radius, speed, dt, reach, search,
      [&](std::ptrdiff_t first, std::ptrdiff_t last, const std::vector<Real>& most, auto&& keep) {
        scan_planes(p.x, normals, points, velocities, first, last, most, tile_reach, keep);
      },
      closes, st);
  std::uint32_t wall = static_cast<std::uint32_t>(planes.size());
  for (const Collider& c : colliders) {
    // A collider's speed varies over it: its particles' reach stays a cell.
    const ColliderPose now = c.pose(time), next = c.pose(time + dt);
    const Vec3 margin = Vec3::Constant(widest + cell);
    const Eigen::AlignedBox<Real, 3> near(now.bounds.min() - margin, now.bounds.max() + margin);
    find_contacts(
        particle_radius, speed, dt, {{c.boundary, c.friction, cell, wall++}}, search,
        [&](std::ptrdiff_t first, std::ptrdiff_t last, const std::vector<Real>& most, auto&& keep) {
          ColliderProbe probe(c);  // the chunk's particles lie in cell order: nearby lookups
          for (std::ptrdiff_t q = first; q < last; ++q) {
            const Vec3& x = p.x[q];
            if (!near.contains(x)) continue;
            const Vec3 x0 = now.to_rest(x);
            if (probe.phi(x0) >= most[0]) continue;  // the normal only where needed
            const SdfSample s = probe.sample(x0);
            if (s.normal.squaredNorm() == 0) continue;
            const Vec3 normal = now.rotation * s.normal;
            keep(q, 0, WallHit{s.phi, normal, next.velocity_at(x), x - s.phi * normal});
          }
        },
        closes, st);
  }
  st.patches = wall * radius.size();
  gather_stencils<K>(dt, p, g, st);
}

}  // namespace

void find_contacts(const std::vector<WallPlane>& planes, const std::vector<Collider>& colliders,
                   Kernel kernel, Real time, Real dt, const Particles& p, const Grid& g,
                   ContactState& st, const std::vector<IndexRange>* search,
                   const BlockSpeeds* speeds) {
  dispatch_kernel(kernel, [&]<Kernel K>() {
    find_contacts_with<K>(planes, colliders, time, dt, p, g, search, speeds, st);
  });
}

Real apply_contact(const std::vector<WallPlane>& planes, const std::vector<Collider>& colliders,
                   const ContactSettings& settings, Kernel kernel, Real time, Real dt,
                   const Particles& p, Grid& g, ContactState& st, ContactMemory& memory,
                   const std::vector<IndexRange>* search, const BlockSpeeds* speeds) {
  find_contacts(planes, colliders, kernel, time, dt, p, g, st, search, speeds);
  if (st.size() == 0) {
    memory.keep({}, {}, {}, dt);
    return 0;
  }
  const Real work = solve_contact(settings, dt, st, memory);
  write_contact_velocities(st, g);
  return work;
}

std::vector<char> contact_chunks(const std::vector<WallPlane>& planes,
                                 const std::vector<Collider>& colliders, const BufferLayers& layers,
                                 Kernel kernel, Real time, const Particles& p, const Grid& g,
                                 std::size_t chunk) {
  const std::size_t n = p.size(), chunks = (n + chunk - 1) / chunk;
  std::vector<char> near(chunks, 1);
  const Real cell = g.h.maxCoeff();
  const std::vector<Real> half = half_spacings(p);
  const Real widest = ParticleRadius{p, half, {}}.widest();
  const Real reach = widest + cell;  // find_contacts' travel is at most a cell
  const Real width = kernel_nodes(kernel);
  // Per plane: its normal, offset, and the distance beyond which a chunk is far from it.
  struct Far {
    Vec3 n;
    Real c, beyond;
  };
  std::vector<Far> far_from;
  for (const WallPlane& w : planes) {
    const Real stencils = width * w.normal.cwiseAbs().dot(g.h);
    far_from.push_back({w.normal, w.normal.dot(w.point + w.offset(time)),
                        std::max(reach, stencils) * (1 + Real(1e-6))});
  }
  std::vector<Eigen::AlignedBox<Real, 3>> boxes;
  for (const Collider& c : colliders) {
    const Vec3 margin = Vec3::Constant(2 * reach + width * cell + cell);
    const Eigen::AlignedBox<Real, 3> b = c.pose(time).bounds;
    boxes.emplace_back(b.min() - margin, b.max() + margin);
  }
  const std::ptrdiff_t count = static_cast<std::ptrdiff_t>(chunks);
  const bool par = n >= static_cast<std::size_t>(kParallelMinItems);
#pragma omp parallel for schedule(static) if (par)
  for (std::ptrdiff_t k = 0; k < count; ++k) {
    const std::size_t first = static_cast<std::size_t>(k) * chunk;
    const std::size_t last = std::min(n, first + chunk);
    Vec3 lo = p.x[first], hi = lo, probe = Vec3::Zero();
    for (std::size_t q = first; q < last; ++q) {
      lo = lo.cwiseMin(p.x[q]);
      hi = hi.cwiseMax(p.x[q]);
      probe += p.x[q] - p.x[q];  // NaN from here on if a coordinate is not finite: no branch
    }
    if (!(probe.array() == 0).all()) continue;
    // The nodes of the chunk's stencils, any kernel's, with a node to spare on each side.
    const Vec3 f = (lo - g.origin).cwiseProduct(g.inv_h), t = (hi - g.origin).cwiseProduct(g.inv_h);
    bool free = true;
    for (int a = 0; a < 3; ++a)
      free = free && static_cast<int>(std::floor(f[a])) - 2 > layers.low[a] &&
             static_cast<int>(std::floor(t[a])) + 3 < layers.high[a];
    for (const Far& w : far_from) {
      const Vec3 corner((w.n.x() > 0 ? lo : hi).x(), (w.n.y() > 0 ? lo : hi).y(),
                        (w.n.z() > 0 ? lo : hi).z());
      free = free && corner.dot(w.n) - w.c > w.beyond;
    }
    for (const auto& b : boxes) free = free && !b.intersects(Eigen::AlignedBox<Real, 3>(lo, hi));
    if (free) near[k] = 0;
  }
  return near;
}

std::vector<IndexRange> marked_ranges(const std::vector<char>& near, std::size_t chunk,
                                      std::size_t particles) {
  std::vector<IndexRange> ranges;
  for (std::size_t k = 0; k < near.size(); ++k) {
    if (!near[k]) continue;
    const std::size_t first = k * chunk, last = std::min(particles, first + chunk);
    if (!ranges.empty() && ranges.back().last == first)
      ranges.back().last = last;
    else
      ranges.push_back({first, last});
  }
  return ranges;
}

}  // namespace mpm
