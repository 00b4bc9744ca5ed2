#pragma once
/// \file assembler.hpp
/// From a scene to an engine: the only engine-side code that reads a Scene
/// and the reference solutions. It validates the scene (validate_scene),
/// then turns it into typed parts (EngineParts): the node lattice and the
/// basis on it, the node mode, the particles seeded in the bodies with the
/// fields the integrator, the materials and the output need, the materials,
/// the Dirichlet sets, the loads (body force, tractions, and what a
/// benchmark brings: the traction history of wobbes et al. eq. 103, the
/// body force and initial velocity of a manufactured solution) and the step
/// settings. A C++ program can build the same parts by hand
/// (examples/dyka_in_code.cpp).
#include "otmpm/engine/engine.hpp"
#include "otmpm/scene/scene.hpp"

#include <functional>

namespace otmpm {

/// The parts of an engine for `scene` in D dimensions. Throws InputError
/// naming the scene key (FILE:LINE when it came from a file) when the scene
/// cannot run: a value or a combination that validate_scene refuses, a
/// boundary box that selects no node, a traction box that selects no
/// particle, a basis that cannot be built on the node set.
template <int D> EngineParts<D> assemble_parts(const Scene& scene);

template <int D> struct SeededBodies;

/// assemble_parts with the particles that `seed(h, lattice)` gives (the
/// grid spacing and the node lattice of the scene) instead of every body's:
/// a rank of a distributed run seeds only the particles of its own cells
/// (distributed/local_parts.cpp; assembly/seeding.hpp, seed_bodies_where).
/// Null `seed`: assemble_parts(scene). With traction loads the seeding
/// must give their surface particles among all (SeededBodies::surfaces:
/// the loads act on the body's surface), else std::logic_error.
template <int D>
EngineParts<D> assemble_parts(const Scene& scene,
                              const std::function<SeededBodies<D>(const Vec<D>&, const CartesianGrid<D>&)>& seed);

/// assemble_parts(scene, seed) whose basis and Dirichlet sets come from
/// `lattice(node lattice)`, called where the whole lattice's would be built
/// (after the seeding), instead of the whole lattice's. Null `lattice`:
/// assemble_parts(scene, seed).
template <int D>
EngineParts<D> assemble_parts(const Scene& scene,
                              const std::function<SeededBodies<D>(const Vec<D>&, const CartesianGrid<D>&)>& seed,
                              const std::function<LatticePart<D>(const CartesianGrid<D>&)>& lattice);

/// The Dirichlet entries of the boundary boxes among `count` points, point
/// i at position(i) (entry node = i): per box in the order of `boundaries`,
/// the points within kBoxTolerance h of it in the order of i. `selected`,
/// when given, gets per box how many of its points have counted[i] != 0
/// (every point when `counted` is null).
template <int D>
Dirichlet<D> boundary_entries(const std::vector<BoundarySection>& boundaries, int count,
                              const std::function<Vec<D>(int)>& position, double h,
                              const std::vector<char>* counted = nullptr, std::vector<long long>* selected = nullptr);

/// InputError naming the first boundary of the scene whose count in
/// `selected` (boundary_entries) is 0: it selects no node.
void require_boundary_nodes(const Scene& scene, const std::vector<long long>& selected);

/// The scene's boundary boxes at time t: each moved along its fixed axes by
/// its prescribed velocity times t (the nodes it holds move so).
std::vector<BoundarySection> boundaries_at(const Scene& scene, double t);

/// The grid spacing of the scene's grid per axis (the spacing particles are seeded with).
template <int D> Vec<D> grid_spacing(const Scene& scene);

/// The node lattice of the scene (node_lattice_box: the grid in `mpm`
/// mode, the bodies' bounding box in `ul` mode) as a grid.
template <int D> CartesianGrid<D> node_grid(const Scene& scene);

/// The basis options of the scene (uGIMP: with the particles' half-width
/// h / (2 n_ppc) of the first body).
template <int D> BasisOptions basis_options(const Scene& scene);

/// Engine<D>(assemble_parts<D>(scene)).
template <int D> Engine<D> assemble(const Scene& scene);

/// Seeds the particles of every [[body]] of the scene on cells of the grid
/// spacing `h` (per axis; the last cell size adjusted so the cells tile the
/// body box exactly), particles_per_cell^D per cell at the Gauss points
/// (volumes = Gauss weights x cell volume) or at the sub-cell centres (equal
/// volumes); sets m, V, V0, rho, length0, material, body and the initial
/// velocity (body velocity, velocity_profile, then the [[initial_velocity]]
/// boxes). InputError naming the key when the bodies do not validate.
template <int D> Particles<D> seed_particles(const Scene& scene, const Vec<D>& h);

} // namespace otmpm
