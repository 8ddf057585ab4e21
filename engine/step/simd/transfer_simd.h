#pragma once
/// \file The transfers in float SIMD (Highway, run-time dispatch over SSE4 / AVX2 / AVX-512).
///
/// Same physics as the scalar path of engine/step/transfer.cpp, in float lanes: results agree
/// with it to float rounding (tests/transfers/test_simd.cpp), and are bit-identical for any
/// thread count on one machine (every sum runs in the same order; a particle's lane does not
/// depend on its neighbours).

#include <functional>
#include <span>

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

/// Name of the instruction set the dispatch chose on this machine, e.g. "AVX3", or nullptr
/// if it has none the SIMD path can use (then the scalar path runs).
const char* target_name();

/// Calls f(name) once per instruction set compiled in that this CPU runs and the SIMD path
/// can use, with the dispatch forced to it (Highway's test hook), then restores the normal
/// choice: so tests on an AVX-512 machine also run the AVX2 and SSE4 code.
void for_each_target(const std::function<void(const char*)>& f);

}  // namespace mpm::simd
