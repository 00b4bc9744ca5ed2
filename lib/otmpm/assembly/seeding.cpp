/// \file seeding.cpp
/// The particles of the scene's bodies (assembler.hpp, seed_particles): a
/// box cut into cells of the grid spacing of its own; a sphere, cylinder or
/// polygon seeded on the cells of the node lattice and kept where the
/// particles lie in the shape; a file body read from its file. A particle
/// of a body inside an earlier body is an input error naming both, unless
/// the later body says overlap = "first" (it is then dropped).
#include "otmpm/assembly/seeding.hpp"

#include "otmpm/geometry/box_cells.hpp"
#include "otmpm/geometry/shapes.hpp"
#include "otmpm/interrupt.hpp"
#include "otmpm/io/particle_file.hpp"
#include "otmpm/scene/file_bodies.hpp"
#include "otmpm/scene/validate.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <numbers>
#include <optional>
#include <utility>

namespace otmpm {

namespace {

template <int D> bool inside_box(const Vec<D>& x, const Vec3& lo, const Vec3& hi) {
  for (int k = 0; k < D; ++k)
    if (x[k] < lo[k] || x[k] > hi[k]) return false;
  return true;
}

/// One particle before it is stored: position, volume, extent per axis, and
/// what a particle file may give (velocity, density; NaN when not given).
template <int D> struct Seed {
  Vec<D> x, extent;
  double V;
  int body;
  Vec<D> v = Vec<D>::Constant(std::numeric_limits<double>::quiet_NaN());
  double density = std::numeric_limits<double>::quiet_NaN();
  int row = -1; ///< its row in the body's particle file
};

/// Cells of the grid spacing h that tile a body box along each axis.
template <int D> Index<D> box_cells(const BodySection& body, const Vec<D>& h) {
  Index<D> cells;
  for (int k = 0; k < D; ++k)
    cells[k] = std::max(1, static_cast<int>(std::lround((body.upper[k] - body.lower[k]) / h[k])));
  return cells;
}

/// The shape of a body (a file body: the cells of its particles).
template <int D> std::unique_ptr<Shape<D>> body_shape(const BodySection& b, const ParticleFile* file) {
  if (b.shape == "sphere") return make_sphere<D>(scene_vec<D>(b.center), b.radius);
  if constexpr (D == 3)
    if (b.shape == "cylinder") return make_cylinder(scene_vec<3>(b.center), scene_vec<3>(b.axis), b.radius, b.length);
  if constexpr (D == 3)
    if (b.shape == "stl") return stl_body_surface(b);
  if constexpr (D >= 2)
    if (b.shape == "mesh") return mesh_body_shape<D>(b);
  if constexpr (D == 2)
    if (b.shape == "polygon") {
      std::vector<Vec<2>> v;
      for (const auto& p : b.vertices) v.emplace_back(p[0], p[1]);
      return make_polygon(v);
    }
  if (file) {
    AlignedVector<Vec<D>> x(static_cast<std::size_t>(file->size()));
    for (int p = 0; p < file->size(); ++p)
      for (int k = 0; k < D; ++k) x[p][k] = file->x[static_cast<std::size_t>(p) * D + k];
    return std::make_unique<ParticleCells<D>>(x, file->volume);
  }
  return make_box<D>(scene_vec<D>(b.lower), scene_vec<D>(b.upper));
}

/// The cells of `lattice` that meet the bounds [lo, hi] of a shape: their
/// box [lower, upper] and count per axis.
template <int D> struct LatticeCells {
  Vec<D> lower, upper;
  Index<D> count;
};
template <int D> LatticeCells<D> lattice_cells(const Vec<D>& lo, const Vec<D>& hi, const CartesianGrid<D>& lattice) {
  const Vec<D> h = lattice.h();
  LatticeCells<D> c;
  Index<D> first;
  for (int k = 0; k < D; ++k) {
    first[k] = std::clamp(static_cast<int>(std::floor((lo[k] - lattice.lower[k]) / h[k])), 0, lattice.cells[k] - 1);
    const int last = std::clamp(static_cast<int>(std::ceil((hi[k] - lattice.lower[k]) / h[k])), first[k] + 1,
                                lattice.cells[k]);
    c.count[k] = last - first[k];
  }
  for (int k = 0; k < D; ++k) {
    c.lower[k] = lattice.lower[k] + first[k] * h[k];
    c.upper[k] = lattice.lower[k] + (first[k] + c.count[k]) * h[k];
  }
  return c;
}

/// The particles of a shape on the cells of `lattice` that meet its bounds,
/// kept where they lie in the shape.
template <int D, class Emit>
void seed_on_lattice(const Shape<D>& shape, const BodySection& b, int body, const CartesianGrid<D>& lattice,
                     Emit&& emit) {
  Vec<D> lo, hi;
  shape.bounds(lo, hi);
  const LatticeCells<D> c = lattice_cells<D>(lo, hi, lattice);
  seed_box_cells<D>(c.lower, c.upper, c.count, b.particles_per_cell, b.placement,
                    [&](const Vec<D>& x, double V, const Vec<D>& extent) {
                      if (shape.contains(x)) emit(Seed<D>{x, extent, V, body});
                    });
}

/// The seed of a particle file's row: position x (D values), volume V,
/// velocity v (D values, or null) and density (NaN when not given).
template <int D> Seed<D> file_seed(const double* x, double V, const double* v, double density, int body, int row) {
  Seed<D> s;
  for (int k = 0; k < D; ++k) s.x[k] = x[k];
  s.V = V;
  s.extent = Vec<D>::Constant(std::pow(s.V, 1.0 / D));
  s.body = body;
  s.row = row;
  if (v)
    for (int k = 0; k < D; ++k) s.v[k] = v[k];
  s.density = density;
  return s;
}

/// The particles of a file body.
template <int D, class Emit> void seed_from_file(const ParticleFile& f, int body, Emit&& emit) {
  const bool v = !f.v.empty();
  const auto density = f.fields.find("density");
  for (int p = 0; p < f.size(); ++p) {
    const std::size_t i = static_cast<std::size_t>(p);
    emit(file_seed<D>(&f.x[i * D], f.volume[i], v ? &f.v[i * D] : nullptr,
                      density != f.fields.end() ? density->second[i] : std::numeric_limits<double>::quiet_NaN(),
                      body, p));
  }
}

/// True when seed s of body b lies in an earlier body and is dropped
/// (overlap = "first"); an input error naming both bodies otherwise.
template <int D>
bool overlapped(const Scene& scene, int b, const std::vector<std::unique_ptr<Shape<D>>>& shapes, const Seed<D>& s) {
  const BodySection& body = scene.bodies[static_cast<std::size_t>(b)];
  for (int a = 0; a < b; ++a) {
    if (!shapes[static_cast<std::size_t>(a)]->contains(s.x)) continue;
    if (body.overlap == "first") return true;
    input_error(body.where, "body '" + body.name + "' overlaps body '" +
                                scene.bodies[static_cast<std::size_t>(a)].name + "': its particle at " +
                                format_point<D>(s.x) + " lies inside '" +
                                scene.bodies[static_cast<std::size_t>(a)].name +
                                "' (set overlap = \"first\" on body '" + body.name +
                                "' to let the earlier body keep the shared region)");
  }
  return false;
}

/// Drops or refuses the seeds of body b that lie in an earlier body.
template <int D>
void resolve_overlap(const Scene& scene, int b, const std::vector<std::unique_ptr<Shape<D>>>& shapes,
                     std::vector<Seed<D>>& seeds) {
  std::erase_if(seeds, [&](const Seed<D>& s) { return overlapped<D>(scene, b, shapes, s); });
}

/// Reads body b's particle file (a file body) and adds its shape to
/// `shapes` (for the overlap of later bodies).
template <int D>
std::optional<ParticleFile> open_body(const Scene& scene, int b, std::vector<std::unique_ptr<Shape<D>>>& shapes) {
  const BodySection& body = scene.bodies[static_cast<std::size_t>(b)];
  std::optional<ParticleFile> file;
  if (body.shape == "file") {
    try {
      // reserved for the scene reader's count when it read this file
      const ParticleFileRules rules = particle_file_rules(scene, body);
      file = read_particle_file(body.file, D, body.file_read == body.file ? body.file_particles : -1, &rules);
    } catch (const InputError& e) {
      input_error(scene.locate("body." + body.name + ".file"), e.what());
    }
  }
  try {
    shapes.push_back(body_shape<D>(body, file ? &*file : nullptr));
  } catch (const InputError& e) {
    input_error(body.where, "body '" + body.name + "': " + e.what());
  }
  return file;
}

/// Calls emit(seed) for every particle of body b in seeding order (before
/// the overlap with earlier bodies is resolved); its file's extra columns
/// go to result.file_state.
template <int D, class Emit>
void generate_body(const Scene& scene, int b, const Vec<D>& h, const CartesianGrid<D>& lattice, const Shape<D>& shape,
                   const ParticleFile* file, SeededBodies<D>& result, Emit&& emit) {
  const BodySection& body = scene.bodies[static_cast<std::size_t>(b)];
  if (body.shape == "box") {
    seed_box_cells<D>(scene_vec<D>(body.lower), scene_vec<D>(body.upper), box_cells<D>(body, h), body.particles_per_cell,
                      body.placement, [&](const Vec<D>& x, double V, const Vec<D>& extent) {
                        emit(Seed<D>{x, extent, V, b});
                      });
  } else if (body.shape == "mesh") {
    if constexpr (D >= 2)
      seed_mesh_body<D>(body, dynamic_cast<const ElementUnion<D>&>(shape), [&](const Vec<D>& x, double V) {
        emit(Seed<D>{x, Vec<D>::Constant(std::pow(V, 1.0 / D)), V, b});
      });
  } else if (file) {
    seed_from_file<D>(*file, b, emit);
    for (const auto& [name, values] : file->fields)
      if (name != "density") result.file_state.push_back({name, b, values});
  } else {
    seed_on_lattice<D>(shape, body, b, lattice, emit);
  }
}

/// True for a body seeded on the lattice and kept inside its shape (not a
/// box, which its cells tile exactly, nor a file body).
bool lattice_shape(const BodySection& body) { return body.shape != "box" && body.shape != "file"; }

/// Scales the volumes of seeds [first, end) of a body by volume_factor
/// (`seeded`: the volume of all the body's seeds, some of which a rank may not hold).
/// Multiplies the volumes of seeds [first, end) by `factor`.
template <int D> void scale_seeds(double factor, std::vector<Seed<D>>& seeds, std::size_t first) {
  if (factor == 1.0) return;
  for (std::size_t i = first; i < seeds.size(); ++i) seeds[i].V *= factor;
}

template <int D>
void scale_volumes(const BodySection& body, const Shape<D>& shape, double seeded, std::vector<Seed<D>>& seeds,
                   std::size_t first) {
  if (!lattice_shape(body)) return;
  scale_seeds<D>(volume_factor(body, seeded, shape.measure()), seeds, first);
}

/// The particles of body b (and its shape, for the overlap of later bodies).
template <int D>
std::vector<Seed<D>> seed_body(const Scene& scene, int b, const Vec<D>& h, const CartesianGrid<D>& lattice,
                               std::vector<std::unique_ptr<Shape<D>>>& shapes, SeededBodies<D>& result) {
  const BodySection& body = scene.bodies[static_cast<std::size_t>(b)];
  std::vector<Seed<D>> seeds;
  const std::optional<ParticleFile> file = open_body<D>(scene, b, shapes);
  if (body.shape == "box") {
    std::size_t n = 1;
    const Index<D> cells = box_cells<D>(body, h);
    for (int k = 0; k < D; ++k) n *= static_cast<std::size_t>(cells[k]) * static_cast<std::size_t>(body.particles_per_cell);
    seeds.reserve(n); // no growth by doubling: peak memory
  } else if (file) {
    seeds.reserve(static_cast<std::size_t>(file->size())); // every row is a seed (before the overlap)
  }
  generate_body<D>(scene, b, h, lattice, *shapes.back(), file ? &*file : nullptr, result,
                   [&seeds](const Seed<D>& s) { seeds.push_back(s); });
  if (seeds.empty()) no_particle(body);
  resolve_overlap<D>(scene, b, shapes, seeds);
  double seeded = 0.0;
  for (const Seed<D>& s : seeds) seeded += s.V;
  scale_volumes<D>(body, *shapes.back(), seeded, seeds, 0);
  return seeds;
}

int material_index(const Scene& scene, const BodySection& body) {
  for (std::size_t i = 0; i < scene.materials.size(); ++i)
    if (scene.materials[i].name == body.material) return static_cast<int>(i);
  input_error(scene.locate("body." + body.name + ".material"),
              "body '" + body.name + "' uses undefined material '" + body.material + "'");
}

template <int D> Vec<D> initial_body_velocity(const BodySection& body, const Vec<D>& x) {
  Vec<D> v = scene_vec<D>(body.velocity);
  if (body.velocity_profile && *body.velocity_profile == "sin_x") {
    const double s = (x[0] - body.lower[0]) / (body.upper[0] - body.lower[0]);
    v *= std::sin(std::numbers::pi * s);
  }
  return v;
}

/// Stores the seeds as particles with mass, material and initial velocity.
template <int D> void store(const Scene& scene, const std::vector<Seed<D>>& seeds, Particles<D>& P) {
  std::vector<int> material; // per body
  for (const BodySection& body : scene.bodies) material.push_back(material_index(scene, body));
  P.resize(static_cast<int>(seeds.size()));
  for (int p = 0; p < P.size(); ++p) {
    const Seed<D>& sd = seeds[static_cast<std::size_t>(p)];
    const BodySection& body = scene.bodies[static_cast<std::size_t>(sd.body)];
    const int mat = material[static_cast<std::size_t>(sd.body)];
    const double density = std::isnan(sd.density) ? scene.materials[static_cast<std::size_t>(mat)].density : sd.density;
    P.x[p] = P.X[p] = sd.x;
    P.V[p] = P.V0[p] = sd.V;
    P.rho[p] = density;
    P.m[p] = density * sd.V;
    P.material[p] = mat;
    P.body[p] = sd.body;
    P.length0[p] = sd.extent;
    P.v[p] = std::isnan(sd.v[0]) ? initial_body_velocity<D>(body, sd.x) : sd.v;
    for (const InitialVelocitySection& iv : scene.initial_velocities)
      if (inside_box<D>(sd.x, iv.lower, iv.upper)) P.v[p] = scene_vec<D>(iv.velocity);
  }
}

/// The box where the seeds of each body lie (its shape's bounds; a file
/// body's: the bounds of its particles' cubes that the scene reader found
/// when it read the file, BodySection::lower/upper - no pass over the file
/// here; widened for round-off), found when first asked for, or none when
/// that is not known before the body is seeded (a shape refused later, in
/// turn, or a file body of a scene built in code, without the reader's
/// bounds).
template <int D> class BodyBoxes {
public:
  using Box = std::pair<Vec<D>, Vec<D>>;
  explicit BodyBoxes(const Scene& scene)
      : scene_(scene), memo_(scene.bodies.size()), relied_(scene.bodies.size(), 0) {}

  /// The box of body a.
  const std::optional<Box>& of(std::size_t a) {
    if (!memo_[a]) memo_[a] = find(scene_.bodies[a]);
    return *memo_[a];
  }

  /// Notes that an earlier body's shape is built on the box of body a (found).
  void rely_on(std::size_t a) { relied_[a] = 1; }

  /// The box of body a if an earlier body's shape was built on it, else null.
  const Box* relied_on(std::size_t a) const { return relied_[a] ? &**memo_[a] : nullptr; }

private:
  std::optional<Box> find(const BodySection& body) const {
    Vec<D> lo, hi;
    if (body.shape == "file") {
      if (body.file_particles <= 0 || body.file_read != body.file) return std::nullopt; // not read by the scene reader
      lo = scene_vec<D>(body.lower), hi = scene_vec<D>(body.upper);
    } else {
      try {
        body_shape<D>(body, nullptr)->bounds(lo, hi);
      } catch (const InputError&) {
        return std::nullopt;
      }
    }
    const Vec<D> margin = 1e-6 * (hi - lo) + 1e-9 * (lo.cwiseAbs() + hi.cwiseAbs());
    return Box{lo - margin, hi + margin};
  }

  const Scene& scene_;
  std::vector<std::optional<std::optional<Box>>> memo_; // outer: found yet
  std::vector<char> relied_;                            // per body: rely_on was called
};

/// The boxes where the seeds of the bodies after b lie, or none when one of
/// them is not known before it is seeded.
template <int D>
std::optional<std::vector<std::pair<Vec<D>, Vec<D>>>> later_boxes(const Scene& scene, int b, BodyBoxes<D>& known) {
  std::vector<std::pair<Vec<D>, Vec<D>>> boxes;
  for (std::size_t a = static_cast<std::size_t>(b) + 1; a < scene.bodies.size(); ++a) {
    const auto& box = known.of(a);
    if (!box) return std::nullopt;
    boxes.push_back(*box);
  }
  return boxes;
}

/// The filter of a file body's shape (ParticleCells::Builder): only the
/// cubes that meet a later body's seeds are asked about (the overlap test).
/// With a filter, the later bodies' boxes are noted as relied on
/// (BodyBoxes::rely_on: a later file body's rows are checked against its box).
template <int D>
typename ParticleCells<D>::Filter later_filter(const Scene& scene, int b, BodyBoxes<D>& known) {
  auto boxes = later_boxes<D>(scene, b, known);
  if (!boxes) return {};
  for (std::size_t a = static_cast<std::size_t>(b) + 1; a < scene.bodies.size(); ++a) known.rely_on(a);
  return [boxes = std::move(*boxes)](const Vec<D>& lo, const Vec<D>& hi) {
    for (const auto& [blo, bhi] : boxes)
      if ((lo.array() <= bhi.array()).all() && (hi.array() >= blo.array()).all()) return true;
    return false;
  };
}

/// Where the further columns of a file body's rows go: per column of
/// ParticleColumns::fields its entry of out.file_state (-1 for density,
/// which is no state variable), and the column of density (-1: none).
struct FileColumns {
  std::vector<int> entry;
  int density = -1;
};

/// Adds the file_state entries of body b's columns (empty: the kept rows'
/// values are appended as they come).
template <int D> FileColumns file_columns(const ParticleColumns& columns, int b, SeededBodies<D>& out) {
  FileColumns c;
  for (std::size_t i = 0; i < columns.fields.size(); ++i) {
    if (columns.fields[i] == "density") {
      c.density = static_cast<int>(i);
      c.entry.push_back(-1);
      continue;
    }
    c.entry.push_back(static_cast<int>(out.file_state.size()));
    out.file_state.push_back({columns.fields[i], b, {}});
  }
  return c;
}

/// The seed of row i of a block of a file body's rows (row: `kept`).
template <int D> Seed<D> row_seed(const ParticleRows& rows, std::size_t i, const FileColumns& c, int b, int kept) {
  const double rho = c.density >= 0 ? rows.fields[static_cast<std::size_t>(c.density)][i]
                                    : std::numeric_limits<double>::quiet_NaN();
  return file_seed<D>(&rows.x[i * D], rows.volume[i], rows.v.empty() ? nullptr : &rows.v[i * D], rho, b, kept);
}

/// InputError unless the rows' positions lie in `box`, the box an earlier
/// file body's shape was built on (BodyBoxes: from the scene reader's pass
/// over the file): else that shape may lack the cubes the overlap test asks
/// about - the file changed after the scene was read.
template <int D>
void require_in_box(const ParticleRows& rows, const typename BodyBoxes<D>::Box* box, const std::string& path) {
  if (!box) return;
  for (std::size_t i = 0; i < static_cast<std::size_t>(rows.size()); ++i) {
    const Vec<D> x(Eigen::Map<const Vec<D>>(&rows.x[i * D]));
    const bool inside = (x.array() >= box->first.array()).all() && (x.array() <= box->second.array()).all();
    require(inside, path, ": row ", rows.first + static_cast<long long>(i), ": position ", format_point<D>(x),
            " lies outside the particles' bounds read with the scene",
            " (the file changed after the scene was read)");
  }
}

/// Streams body b's particle file (a file body of seed_bodies_where), its
/// one pass over the file: emit(seed) for every row in file order, which
/// returns whether it keeps the seed (seed.row: the index of its values in
/// the body's out.file_state, which hold the kept rows only), then adds the
/// body's shape to `shapes` (holding only the cubes near the later bodies'
/// boxes in `known`). An error of a seed (overlap) is raised after the file
/// was read, as when it was read whole before seeding (a bad row first).
template <int D, class Emit>
void stream_file_body(const Scene& scene, int b, std::vector<std::unique_ptr<Shape<D>>>& shapes, BodyBoxes<D>& known,
                      SeededBodies<D>& out, Emit&& emit) {
  const BodySection& body = scene.bodies[static_cast<std::size_t>(b)];
  typename ParticleCells<D>::Builder cells(later_filter<D>(scene, b, known));
  FileColumns columns;
  int kept = 0;
  std::exception_ptr refused;
  const typename BodyBoxes<D>::Box* box = known.relied_on(static_cast<std::size_t>(b));
  auto each = [&](const ParticleColumns& layout, const ParticleRows& rows) {
    if (rows.first == 0) columns = file_columns<D>(layout, b, out);
    require_in_box<D>(rows, box, body.file);
    for (std::size_t i = 0; i < static_cast<std::size_t>(rows.size()); ++i) {
      cells.add(Vec<D>(Eigen::Map<const Vec<D>>(&rows.x[i * D])), rows.volume[i]);
      try {
        if (refused || !emit(row_seed<D>(rows, i, columns, b, kept))) continue;
      } catch (const InputError&) {
        refused = std::current_exception();
        continue;
      }
      ++kept;
      for (std::size_t f = 0; f < columns.entry.size(); ++f)
        if (columns.entry[f] >= 0) out.file_state[static_cast<std::size_t>(columns.entry[f])].values.push_back(rows.fields[f][i]);
    }
  };
  const ParticleFileRules rules = particle_file_rules(scene, body);
  try {
    stream_particle_file(body.file, D, each, kParticleChunk, &rules);
  } catch (const InputError& e) {
    input_error(scene.locate("body." + body.name + ".file"), e.what());
  }
  try {
    shapes.push_back(cells.finish());
  } catch (const InputError& e) {
    input_error(body.where, "body '" + body.name + "': " + e.what());
  }
  if (refused) std::rethrow_exception(refused);
}

/// Stores the particles `kept` (and their file rows) in `out`.
template <int D> void store_kept(const Scene& scene, const std::vector<Seed<D>>& kept, SeededBodies<D>& out) {
  store<D>(scene, kept, out.particles);
  out.file_row.resize(kept.size());
  for (std::size_t p = 0; p < kept.size(); ++p) out.file_row[p] = kept[p].row;
}

/// Calls f(c, i0, i1, number) for every line along axis 0 of the seeding
/// cells of `range` within `cells` cells per axis, in number order (axis 0
/// fastest): its cells c + (i - c[0]) e_0 for i in [i0, i1) (c[0] = i0),
/// the first of number `number`, skipping the cells outside [from, to).
template <int D, class F> void for_each_line(const Index<D>& cells, const CellRange<D>& range, F&& f) {
  Index<D> lo, hi;
  for (int k = 0; k < D; ++k) lo[k] = std::max(range.lo[k], 0), hi[k] = std::min(range.hi[k], cells[k]);
  for (int k = 0; k < D; ++k)
    if (hi[k] <= lo[k]) return;
  Index<D> c = lo;
  bool whole_lines = true; // the box spans axes 1.. whole: start at the line of `from`
  for (int k = 1; k < D; ++k) whole_lines = whole_lines && lo[k] == 0 && hi[k] == cells[k];
  if (whole_lines && range.from > 0)
    for (long long line = range.from / cells[0], k = 1; k < D; ++k) {
      c[k] = static_cast<int>(line % cells[k]);
      line /= cells[k];
      if (k == D - 1 && line > 0) return; // beyond the last line
    }
  while (true) {
    long long line = 0; // the number of cell (0, c[1], ...)
    for (int k = D - 1; k >= 1; --k) line = line * cells[k] + c[k];
    line *= cells[0];
    if (line + lo[0] >= range.to) return; // every later line lies beyond too
    const long long i0 = std::max<long long>(lo[0], range.from - line), i1 = std::min<long long>(hi[0], range.to - line);
    if (i0 < i1) {
      c[0] = static_cast<int>(i0);
      f(static_cast<const Index<D>&>(c), static_cast<int>(i0), static_cast<int>(i1), line + i0);
    }
    int k = 1;
    for (; k < D; ++k) {
      if (++c[k] < hi[k]) break;
      c[k] = lo[k];
    }
    if (k == D) return;
  }
}

/// The particles of one cell of `box`.
template <int D> long long box_particles(const BoxCells<D>& box) {
  long long n = 1;
  for (int k = 0; k < D; ++k) n *= box.per_axis();
  return n;
}

/// The volumes of one cell's particles of `box`, in order (the same in
/// every cell), when the body's tally of seeded volume is used (a shape on
/// the lattice scaled to its exact volume: body_volume_factor); else none.
template <int D> std::vector<double> cell_volumes(const BodySection& body, const BoxCells<D>& box) {
  std::vector<double> V;
  if (!lattice_shape(body) || body.volume != "exact") return V;
  box.cell(Index<D>{}, [&V](const Vec<D>&, double v, const Vec<D>&) { V.push_back(v); });
  return V;
}

/// What seed_run needs of a body seeded by cells in a counting pass.
template <int D> struct RunSeeding {
  const BodySection& body;
  const BoxCells<D>& box;
  const Shape<D>* inside;                                 ///< the body's shape (null: a box, which its cells tile)
  const std::vector<std::unique_ptr<Shape<D>>>& earlier; ///< the shapes of the bodies before it
  const TakeRun<D>& take;
  std::vector<double> volumes; ///< of one cell's particles, in order, when BodyTally::seeded is used; else empty
  long long per_cell;
};

/// The box of the particles of cells [i0, i1) along axis 0 from cell c (BoxCells::coordinate).
template <int D> void run_box(const BoxCells<D>& box, const Index<D>& c, int i0, int i1, Vec<D>& lo, Vec<D>& hi) {
  for (int k = 0; k < D; ++k) {
    const int first = k == 0 ? i0 : c[k], last = k == 0 ? i1 - 1 : c[k];
    lo[k] = box.coordinate(k, first, 0), hi[k] = box.coordinate(k, last, 0);
    for (int q = 1; q < box.per_axis(); ++q)
      lo[k] = std::min(lo[k], box.coordinate(k, first, q)), hi[k] = std::max(hi[k], box.coordinate(k, last, q));
  }
}

/// Where the box [lo, hi] lies against the earlier bodies: outside all
/// (nothing dropped), inside one (every particle in an earlier body), or unknown.
template <int D>
typename Shape<D>::Side earlier_side(const std::vector<std::unique_ptr<Shape<D>>>& earlier, std::size_t count,
                                     const Vec<D>& lo, const Vec<D>& hi) {
  using Side = typename Shape<D>::Side;
  Side all = Side::outside;
  for (std::size_t a = 0; a < count; ++a) {
    const Side s = earlier[a]->side(lo, hi);
    if (s == Side::inside) return s;
    if (s == Side::unknown) all = s;
  }
  return all;
}

/// The counting pass over the cells [i0, i1) along axis 0 from cell c
/// (number `number`) of body b (seed_cells_where with `take`): a run
/// outside the shape is skipped, one whose particles are all placed is
/// offered to `take`, one whose particles an earlier body all drops
/// (overlap = "first") is tallied; the others are halved, and a single
/// cell left is seeded by one(c, number), particle by particle.
template <int D, class One>
void seed_run(const RunSeeding<D>& r, int b, Index<D> c, int i0, int i1, long long number, BodyTally& t, One&& one) {
  using Side = typename Shape<D>::Side;
  interrupt_point("seeding a body");
  CellRun<D> run{b, number, i1 - i0, r.per_cell, c, Vec<D>::Zero(), Vec<D>::Zero(), &r.box};
  run.c[0] = i0;
  run_box<D>(r.box, run.c, i0, i1, run.lower, run.upper);
  const Side side = r.inside ? r.inside->side(run.lower, run.upper) : Side::inside;
  if (side == Side::outside) return;
  if (side == Side::inside) {
    const Side earlier = earlier_side<D>(r.earlier, static_cast<std::size_t>(b), run.lower, run.upper);
    if (earlier == Side::outside && r.take(run)) {
      t.generated += run.cells * r.per_cell, t.placed += run.cells * r.per_cell;
      for (long long i = 0; i < run.cells; ++i)
        for (double V : r.volumes) t.seeded += V;
      return;
    }
    if (earlier == Side::inside && r.body.overlap == "first") {
      t.generated += run.cells * r.per_cell;
      return;
    }
  }
  if (i1 - i0 == 1) return one(run.c, number);
  const int mid = i0 + (i1 - i0) / 2;
  seed_run<D>(r, b, c, i0, mid, number, t, one);
  seed_run<D>(r, b, c, mid, i1, number + (mid - i0), t, one);
}

} // namespace

template <int D> double body_measure(const BodySection& body) {
  if (body.shape == "file") return std::numeric_limits<double>::quiet_NaN();
  return body_shape<D>(body, nullptr)->measure();
}

template <int D> double body_volume_factor(const BodySection& body, double seeded) {
  if (!lattice_shape(body) || body.volume != "exact") return 1.0;
  return volume_factor(body, seeded, body_measure<D>(body));
}

double volume_factor(const BodySection& body, double seeded, double exact) {
  return body.volume == "exact" && seeded > 0.0 ? exact / seeded : 1.0;
}

[[noreturn]] void no_particle(const BodySection& body) {
  input_error(body.where, "body '" + body.name + "' holds no particle (is it smaller than a cell?)");
}

template <int D>
std::pair<Index<D>, Index<D>> BodyCells<D>::near(const Vec<D>& lo, const Vec<D>& hi) const {
  Index<D> first{}, last = cells;
  for (int k = 0; k < D && by_cells; ++k) {
    const double a = std::floor((lo[k] - lower[k]) / size[k]) - 1, b = std::ceil((hi[k] - lower[k]) / size[k]) + 1;
    first[k] = static_cast<int>(std::clamp(a, 0.0, static_cast<double>(cells[k])));
    last[k] = static_cast<int>(std::clamp(b, static_cast<double>(first[k]), static_cast<double>(cells[k])));
  }
  return {first, last};
}

template <int D>
std::vector<BodyCells<D>> body_cells(const Scene& scene, const Vec<D>& h, const CartesianGrid<D>& lattice) {
  std::vector<BodyCells<D>> out;
  for (const BodySection& b : scene.bodies) {
    BodyCells<D> c;
    if (b.shape == "box") {
      c.by_cells = true;
      c.cells = box_cells<D>(b, h);
      c.lower = scene_vec<D>(b.lower);
      c.upper = scene_vec<D>(b.upper);
    } else if (b.shape != "file" && b.shape != "mesh") {
      Vec<D> lo, hi;
      try {
        body_shape<D>(b, nullptr)->bounds(lo, hi);
      } catch (const InputError& e) {
        input_error(b.where, "body '" + b.name + "': " + e.what());
      }
      const LatticeCells<D> l = lattice_cells<D>(lo, hi, lattice);
      c.by_cells = true;
      c.cells = l.count;
      c.lower = l.lower;
      c.upper = l.upper;
    }
    for (int k = 0; k < D && c.by_cells; ++k) c.size[k] = (c.upper[k] - c.lower[k]) / c.cells[k];
    out.push_back(c);
  }
  return out;
}

template <int D>
SeededBodies<D> seed_bodies(const Scene& scene, const Vec<D>& h, const CartesianGrid<D>& lattice) {
  validate_seeding<D>(scene, h);
  SeededBodies<D> result;
  std::vector<std::unique_ptr<Shape<D>>> shapes;
  std::vector<Seed<D>> seeds;
  for (int b = 0; b < static_cast<int>(scene.bodies.size()); ++b) {
    std::vector<Seed<D>> body = seed_body<D>(scene, b, h, lattice, shapes, result);
    if (seeds.empty()) seeds = std::move(body); // no copy of the common single body (peak memory)
    else seeds.insert(seeds.end(), body.begin(), body.end());
  }
  WallSides<D> sides(scene, h);
  for (std::size_t p = 0; p < seeds.size(); ++p) sides.visit(seeds[p].x, seeds[p].body, {0, static_cast<long long>(p)});
  sides.refuse();
  store<D>(scene, seeds, result.particles);
  result.file_row.resize(seeds.size());
  for (std::size_t p = 0; p < seeds.size(); ++p) result.file_row[p] = seeds[p].row;
  return result;
}

template <int D>
std::vector<BodyTally> seed_cells_where(const Scene& scene, const Vec<D>& h, const CartesianGrid<D>& lattice,
                                        const std::function<CellRange<D>(int)>& range,
                                        const std::function<long long(const SeedSpot&, const Vec<D>&)>& place,
                                        SeededBodies<D>* result, SeedSpot* at,
                                        const std::vector<double>* factors, const TakeRun<D>& take) {
  validate_seeding<D>(scene, h, false); // a share's size is checked by its maker
  require<std::invalid_argument>(!take || !result, "seed_cells_where: runs are taken whole only in a counting pass");
  SeededBodies<D> unused;
  SeededBodies<D>& out = result ? *result : unused;
  SeedSpot unused_spot;
  SeedSpot& where = at ? *at : unused_spot;
  std::vector<std::unique_ptr<Shape<D>>> shapes;
  std::vector<Seed<D>> kept;
  BodyBoxes<D> known(scene); // the later bodies' boxes (file bodies' shapes hold only the cubes near them)
  const std::vector<BodyCells<D>> cells = body_cells<D>(scene, h, lattice);
  std::vector<BodyTally> tally(scene.bodies.size());
  for (int b = 0; b < static_cast<int>(scene.bodies.size()); ++b) {
    const BodySection& body = scene.bodies[static_cast<std::size_t>(b)];
    const BodyCells<D>& bc = cells[static_cast<std::size_t>(b)];
    BodyTally& t = tally[static_cast<std::size_t>(b)];
    where = {b, 0, -1};
    long long placed_in_cell = 0;
    // A seed inside an earlier body is refused or dropped as it comes (the
    // serial seeding's first such seed is the one named in the error).
    const std::size_t first = kept.size(); // the body's first kept seed
    auto emit = [&](const Seed<D>& s) {
      where.index = t.generated++;
      if (overlapped<D>(scene, b, shapes, s)) return false;
      ++t.placed;
      t.seeded += s.V;
      const long long id = place(SeedSpot{b, where.cell, placed_in_cell++}, s.x);
      if (id < 0 || !result) return false;
      kept.push_back(s);
      out.ids.push_back(id);
      return true;
    };
    bool whole = true; // the pass generates every particle of the body
    if (body.shape == "file") {
      stream_file_body<D>(scene, b, shapes, known, out, emit); // its rows are not held beyond those kept
    } else if (!bc.by_cells) {
      open_body<D>(scene, b, shapes);
      generate_body<D>(scene, b, h, lattice, *shapes.back(), nullptr, out, emit);
    } else {
      open_body<D>(scene, b, shapes);
      const Shape<D>* inside = body.shape == "box" ? nullptr : shapes.back().get();
      const BoxCells<D> box(bc.lower, bc.upper, bc.cells, body.particles_per_cell, body.placement);
      const CellRange<D> r = range(b);
      for (int k = 0; k < D; ++k) whole = whole && r.lo[k] <= 0 && r.hi[k] >= bc.cells[k];
      whole = whole && r.from <= 0 && r.to >= bc.count();
      auto one = [&](const Index<D>& c, long long number) {
        where.cell = number;
        placed_in_cell = 0;
        box.cell(c, [&](const Vec<D>& x, double V, const Vec<D>& extent) {
          if (!inside || inside->contains(x)) emit(Seed<D>{x, extent, V, b});
        });
      };
      const RunSeeding<D> runs{body, box, inside, shapes, take, cell_volumes<D>(body, box), box_particles<D>(box)};
      for_each_line<D>(bc.cells, r, [&](Index<D> c, int i0, int i1, long long number) {
        if (take) return seed_run<D>(runs, b, c, i0, i1, number, t, one);
        for (int i = i0; i < i1; ++i, ++number) {
          interrupt_point("seeding a body");
          c[0] = i;
          one(c, number);
        }
      });
    }
    if (whole && t.generated == 0) {
      where.index = std::numeric_limits<long long>::max();
      no_particle(body);
    }
    // a body generated whole has its volume here; one split over the ranks
    // has the factor of the ranks' volumes summed (share_seeding)
    if (factors) scale_seeds<D>((*factors)[static_cast<std::size_t>(b)], kept, first);
    else if (whole) scale_volumes<D>(body, *shapes.back(), t.seeded, kept, first);
  }
  if (result) store_kept<D>(scene, kept, out);
  return tally;
}

template <int D>
long long seed_bodies_where(const Scene& scene, const Vec<D>& h, const CartesianGrid<D>& lattice,
                            const std::function<bool(long long, const Vec<D>&)>& keep, SeededBodies<D>* result) {
  long long id = 0;
  WallSides<D> sides(scene, h);
  seed_cells_where<D>(
      scene, h, lattice,
      [](int) {
        CellRange<D> all;
        all.hi.fill(std::numeric_limits<int>::max());
        return all;
      },
      [&](const SeedSpot& s, const Vec<D>& x) {
        sides.visit(x, s.body, seeding_order(s));
        const long long mine = id++;
        return keep(mine, x) ? mine : -1;
      },
      result);
  sides.refuse();
  return id;
}

template double body_measure<1>(const BodySection&);
template double body_measure<2>(const BodySection&);
template double body_measure<3>(const BodySection&);
template double body_volume_factor<1>(const BodySection&, double);
template double body_volume_factor<2>(const BodySection&, double);
template double body_volume_factor<3>(const BodySection&, double);
template SeededBodies<1> seed_bodies<1>(const Scene&, const Vec<1>&, const CartesianGrid<1>&);
template SeededBodies<2> seed_bodies<2>(const Scene&, const Vec<2>&, const CartesianGrid<2>&);
template SeededBodies<3> seed_bodies<3>(const Scene&, const Vec<3>&, const CartesianGrid<3>&);
template <int D>
TractionSurfaces<D>::TractionSurfaces(const Scene& scene, double tol)
    : loads_(scene.tractions), tol_(tol), ends_(scene.tractions.size()) {
  for (const TractionSection& ts : loads_) axis_.push_back(traction_axis<D>(ts));
}

template <int D> void TractionSurfaces<D>::visit(long long id, const Vec<D>& X) {
  for (std::size_t i = 0; i < loads_.size(); ++i) {
    const int axis = axis_[i];
    auto [it, fresh] = ends_[i].try_emplace(column_key<D>(X, axis, tol_), End{id, id, X, X});
    if (fresh) continue;
    End& e = it->second;
    if (X[axis] < e.x_first[axis]) e.first = id, e.x_first = X;
    if (X[axis] > e.x_last[axis]) e.last = id, e.x_last = X;
  }
}

template <int D> void TractionSurfaces<D>::finish() {
  ids_.assign(loads_.size(), {});
  selects_.assign(loads_.size(), 0);
  for (std::size_t i = 0; i < loads_.size(); ++i) {
    for (const auto& [column, e] : ends_[i]) {
      ids_[i].push_back(e.first), ids_[i].push_back(e.last);
      for (const Vec<D>* x : {&e.x_first, &e.x_last})
        if (inside_box<D>(*x, loads_[i].lower, loads_[i].upper)) selects_[i] = 1;
    }
    std::sort(ids_[i].begin(), ids_[i].end());
    ends_[i].clear(); // the columns are not needed any more
  }
}

template <int D>
WallSides<D>::WallSides(const Scene& scene, const Vec<D>& h) : scene_(scene), tol_(kBoxTolerance * h.minCoeff()) {
  for (const WallSection& w : scene.walls)
    walls_.push_back({scene_vec<D>(w.point), Vec<D>(first_components(w.normal, D).template head<D>().stableNormalized())});
  behind_.assign(walls_.size() * scene.bodies.size(), Behind{});
}

template <int D> void WallSides<D>::visit(const Vec<D>& x, int body, const Order& at) {
  for (std::size_t w = 0; w < walls_.size(); ++w) {
    if ((x - walls_[w].first).dot(walls_[w].second) >= -tol_) continue;
    Behind& b = behind_[w * scene_.bodies.size() + static_cast<std::size_t>(body)];
    if (b.count++ == 0 || at < b.at) b.first = x, b.at = at;
  }
}

template <int D> bool WallSides<D>::clear(const Vec<D>& lo, const Vec<D>& hi) const {
  for (const auto& [p, n] : walls_) {
    double least = 0.0, scale = 0.0; // the box's least (x - p).n, and the size of its terms
    for (int k = 0; k < D; ++k) {
      const double x = n[k] >= 0.0 ? lo[k] : hi[k];
      least += (x - p[k]) * n[k];
      scale = std::max({scale, std::abs(x), std::abs(p[k])});
    }
    if (least < -tol_ + kSideSlack * scale) return false;
  }
  return true;
}

template <int D> void WallSides<D>::refuse() const {
  for (std::size_t i = 0; i < behind_.size(); ++i) {
    if (behind_[i].count == 0) continue;
    const WallSection& w = scene_.walls[i / scene_.bodies.size()];
    const std::string& body = scene_.bodies[i % scene_.bodies.size()].name;
    input_error(w.where, "body '" + body + "' starts behind wall '" + w.name + "': " +
                             std::to_string(behind_[i].count) + " of its particles (the first at " +
                             format_point<D>(behind_[i].first) +
                             ") lie on the side the wall's normal points away from, where the wall would push "
                             "or hold them from the first step (move the wall or the body, or turn the normal "
                             "to the body's side)");
  }
}

template <int D> std::string WallSides<D>::pack() const {
  std::string out;
  auto put = [&out](const auto& v) { out.append(reinterpret_cast<const char*>(&v), sizeof v); };
  for (const Behind& b : behind_) {
    put(b.count), put(b.at.first), put(b.at.second);
    for (int k = 0; k < D; ++k) put(b.first[k]);
  }
  return out;
}

template <int D> void WallSides<D>::merge(const std::string& packed) {
  const std::size_t bytes = sizeof(long long) * 3 + sizeof(double) * D;
  require<std::invalid_argument>(packed.size() == behind_.size() * bytes, "WallSides::merge: ", packed.size(),
                                 " bytes for ", behind_.size(), " walls and bodies");
  for (std::size_t i = 0; i < behind_.size(); ++i) {
    Behind other;
    const char* p = packed.data() + i * bytes;
    std::memcpy(&other.count, p, sizeof(long long));
    std::memcpy(&other.at.first, p + sizeof(long long), sizeof(long long));
    std::memcpy(&other.at.second, p + 2 * sizeof(long long), sizeof(long long));
    for (int k = 0; k < D; ++k) std::memcpy(&other.first[k], p + 3 * sizeof(long long) + k * sizeof(double), sizeof(double));
    if (other.count == 0) continue;
    Behind& mine = behind_[i];
    if (mine.count == 0 || other.at < mine.at) mine.first = other.first, mine.at = other.at;
    mine.count += other.count;
  }
}

template class WallSides<1>;
template class WallSides<2>;
template class WallSides<3>;

template <int D> std::string TractionSurfaces<D>::pack() const {
  std::string out;
  auto put = [&out](const auto& v) { out.append(reinterpret_cast<const char*>(&v), sizeof v); };
  for (const auto& ends : ends_) {
    put(static_cast<std::uint64_t>(ends.size()));
    for (const auto& [column, e] : ends) {
      put(column), put(e.first), put(e.last);
      for (int k = 0; k < D; ++k) put(e.x_first[k]), put(e.x_last[k]);
    }
  }
  return out;
}

template <int D> void TractionSurfaces<D>::merge(const std::string& packed) {
  std::size_t at = 0;
  auto get = [&](auto& v) {
    require<std::invalid_argument>(at + sizeof v <= packed.size(), "TractionSurfaces::merge: truncated ends");
    std::memcpy(&v, packed.data() + at, sizeof v);
    at += sizeof v;
  };
  for (auto& ends : ends_) {
    std::uint64_t n = 0;
    for (get(n); n > 0; --n) {
      std::array<long long, 2> column;
      End e;
      get(column), get(e.first), get(e.last);
      for (int k = 0; k < D; ++k) get(e.x_first[k]), get(e.x_last[k]);
      auto [it, fresh] = ends.try_emplace(column, e);
      if (fresh) continue;
      End& mine = it->second;
      // as visits in id order keep them: the smallest (largest) coordinate, the earlier id on ties
      const int axis = axis_[static_cast<std::size_t>(&ends - ends_.data())];
      const auto before = [](double a, long long ia, double b, long long ib) { return a < b || (a == b && ia < ib); };
      if (before(e.x_first[axis], e.first, mine.x_first[axis], mine.first)) mine.first = e.first, mine.x_first = e.x_first;
      if (before(-e.x_last[axis], e.last, -mine.x_last[axis], mine.last)) mine.last = e.last, mine.x_last = e.x_last;
    }
  }
}

template <int D> bool TractionSurfaces<D>::surface(std::size_t load, long long id) const {
  return std::binary_search(ids_[load].begin(), ids_[load].end(), id);
}

template class TractionSurfaces<1>;
template class TractionSurfaces<2>;
template class TractionSurfaces<3>;

#define OTMPM_INSTANTIATE(D)                                                                                 \
  template long long seed_bodies_where<D>(const Scene&, const Vec<D>&, const CartesianGrid<D>&,              \
                                          const std::function<bool(long long, const Vec<D>&)>&, SeededBodies<D>*); \
  template std::vector<BodyTally> seed_cells_where<D>(                                                       \
      const Scene&, const Vec<D>&, const CartesianGrid<D>&, const std::function<CellRange<D>(int)>&,          \
      const std::function<long long(const SeedSpot&, const Vec<D>&)>&, SeededBodies<D>*, SeedSpot*,          \
      const std::vector<double>*, const TakeRun<D>&);                                                        \
  template std::vector<BodyCells<D>> body_cells<D>(const Scene&, const Vec<D>&, const CartesianGrid<D>&);    \
  template struct BodyCells<D>;
OTMPM_INSTANTIATE(1)
OTMPM_INSTANTIATE(2)
OTMPM_INSTANTIATE(3)
#undef OTMPM_INSTANTIATE

} // namespace otmpm
