#pragma once
/// \file The transfers in float SIMD (Highway, run-time dispatch over SSE4 / AVX2 / AVX-512).
///
/// Same physics as the scalar path of engine/step/transfer.cpp, in float lanes: results agree
/// with it to float rounding (tests/transfers/test_simd.cpp), and are bit-identical for any
/// thread count on one machine (every sum runs in the same order; a particle's lane does not
/// depend on its neighbours).

#include <functional>
#include <span>
#include <string>

#include "engine/core/particles.h"
#include "engine/scene/scene_desc.h"
#include "engine/step/grid.h"
#include "engine/step/kernels.h"
#include "engine/step/transfer.h"
#include "materials/material.h"

namespace mpm::simd {

/// True if the SIMD path handles `transfer` with `kernel` (PIC, APIC and MLS; FLIP, which
/// keeps a separate force and old velocity, runs the scalar path). The grid must hold fewer
/// than 2^31 nodes (32-bit gather indices).
bool supports(Transfer transfer, Kernel kernel, const Grid& grid);

/// particles_to_grid's scatter (the grid already cleared) with one SIMD lane per stencil node:
/// for each particle of a stencil base cell, all N^3 node contributions at once, summed over
/// the cell's particles in registers, then added to the grid once per cell. The stress of a
/// particle whose object o has a model in fold[o] is computed here, kLanes particles at a time
/// in the scatter's order (engine/step/simd/corotated-inl.h, the same values simd::stress
/// gives), and never stored; the others' is read from p.stress.
void scatter(const Particles& p, const ParticleOrder& order, Transfer transfer, Kernel kernel,
             Real dt, Grid& grid, std::span<const BatchModel> fold = {});

/// grid_to_particles with one SIMD lane per particle, L consecutive particles at a time: the
/// weights computed once per lane set, node velocities gathered from grid.velocity_f (which
/// this fills from grid.velocity). With `advect`, each lane set is then advected in lanes
/// (advect_particle's operations, x + dt v as one FMA) and the counts written there.
void gather(const Grid& grid, Transfer transfer, Kernel kernel, Real dt, Particles& p,
            AdvectStats* advect = nullptr);

/// gather in parts: prepare_gather fills grid.velocity_f from grid.velocity, in rows sized
/// for `kernel`'s stencil (Grid::row_nodes), so gather_range must take the same kernel; each
/// gather_range call gathers particles [first, last) on the calling thread (no parallel
/// region; `first` a multiple of kGatherAlign), in the lane sets gather makes, so every
/// particle gets gather's values. With `advect`, its counts are added there and its speed
/// raised to the range's largest.
void prepare_gather(const Grid& grid, Kernel kernel);
/// The part of gather (after prepare_gather) for particles [first, last), on this thread.
void gather_range(const Grid& grid, Transfer transfer, Kernel kernel, Real dt, Particles& p,
                  std::size_t first, std::size_t last, AdvectStats* advect);
/// What gather_range's `first` must be a multiple of: the widest target's lanes, times four.
inline constexpr std::size_t kGatherAlign = 64;

/// sort_by_cell's keys of particles [first, last): the cell of `kernel`'s stencil base less
/// `lo`, in a box of `ext` cells, x slowest, in double lanes with make_stencil's operations
/// (the same values). The box must hold every base and fewer than 2^31 cells. Writes whole
/// lane sets from `first` and returns how many particles it did (0 without a SIMD target);
/// the caller keys the rest. With `bases`, particle q's stencil base (not less `lo`) also goes
/// to bases[3 (q - first) + axis].
std::size_t cell_keys(const Particles& p, Kernel kernel, const Grid& grid, const Vec3i& lo,
                      const Vec3i& ext, std::size_t first, std::size_t last, std::uint32_t* keys,
                      std::int32_t* bases = nullptr);

/// Name of the instruction set the dispatch chose on this machine, e.g. "AVX3", or nullptr
/// if it has none the SIMD path can use (then the scalar path runs).
const char* target_name();

/// Forces the dispatch to the instruction set `name` (as target_name gives it, e.g. "AVX2")
/// for the rest of the process, so a machine with AVX-512 also times its AVX2 code (mpm
/// bench --simd AVX2); "" restores the normal choice. Returns false, with the normal choice
/// restored, if it is not compiled in, this CPU cannot run it, or the SIMD path cannot use it.
bool force_target(const std::string& name);

/// Calls f(name) once per instruction set compiled in that this CPU runs and the SIMD path
/// can use, with the dispatch forced to it (Highway's test hook), then restores the normal
/// choice: so tests on an AVX-512 machine also run the AVX2 and SSE4 code.
void for_each_target(const std::function<void(const char*)>& f);

}  // namespace mpm::simd
