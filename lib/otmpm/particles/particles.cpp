#include "otmpm/particles/particles.hpp"

#include "otmpm/scene/scene.hpp"
#include "otmpm/scene/validate.hpp"

#include <cmath>
#include <numbers>
#include <stdexcept>

namespace otmpm {

template <int D> void Particles<D>::resize(int n) {
  require<std::invalid_argument>(n >= 0, "Particles::resize: n must be >= 0, got ", n);
  x.assign(n, Vec<D>::Zero());
  X = v = length0 = x;
  m.assign(n, 0.0);
  V = V0 = rho = m;
  eps.assign(n, Mat<D>::Zero());
  sigma = eps;
  material.assign(n, 0);
  body.assign(n, 0);
  a.clear(), F.clear(), lambda.clear(), cell_hint.clear(), x_prev.clear();
}

template <int D> void Particles<D>::allocate_optional(bool with_a, bool with_F, bool with_lambda, bool with_cell_hint) {
  const auto n = static_cast<std::size_t>(size());
  if (with_a) a.assign(n, Vec<D>::Zero());
  if (with_F) F.assign(n, Mat<D>::Identity());
  if (with_lambda) lambda.assign(n, Vec<D>::Zero());
  if (with_cell_hint) cell_hint.assign(n, Index<D>{});
}

void gauss_legendre(int n, std::vector<double>& points, std::vector<double>& weights) {
  if (n < 1) throw InputError("gauss_legendre: order must be >= 1, got " + std::to_string(n));
  constexpr int max_newton = 100;
  constexpr double newton_tol = 1e-15;
  points.assign(n, 0.0);
  weights.assign(n, 0.0);
  for (int i = 0; i < n; ++i) {
    // Chebyshev-like initial guess for the i-th root of P_n, refined by Newton.
    double z = std::cos(std::numbers::pi * (i + 0.75) / (n + 0.5));
    double dp = 1.0;
    for (int it = 0; it < max_newton; ++it) {
      double p0 = 1.0, p1 = z;
      for (int k = 2; k <= n; ++k) {
        const double pk = ((2.0 * k - 1.0) * z * p1 - (k - 1.0) * p0) / k;
        p0 = p1;
        p1 = pk;
      }
      if (n == 1) p0 = 1.0;
      dp = n * (z * p1 - p0) / (z * z - 1.0);
      const double dz = p1 / dp;
      z -= dz;
      if (std::abs(dz) < newton_tol) break;
    }
    points[n - 1 - i] = z;
    weights[n - 1 - i] = 2.0 / ((1.0 - z * z) * dp * dp);
  }
}

namespace {

/// Particle positions (in [0,1] of a cell) and volume fractions per axis.
void cell_pattern(const std::string& placement, int n, std::vector<double>& s,
                  std::vector<double>& w) {
  if (placement == "gauss") {
    gauss_legendre(n, s, w);
    for (int i = 0; i < n; ++i) {
      s[i] = 0.5 * (s[i] + 1.0);
      w[i] *= 0.5;
    }
    return;
  }
  s.resize(n);
  w.assign(n, 1.0 / n);
  for (int i = 0; i < n; ++i) s[i] = (i + 0.5) / n;
}

int material_index(const Scene& scene, const BodySection& body) {
  for (std::size_t i = 0; i < scene.materials.size(); ++i)
    if (scene.materials[i].name == body.material) return static_cast<int>(i);
  input_error(scene.locate("body." + body.name + ".material"),
              "body '" + body.name + "' uses undefined material '" + body.material + "'");
}

template <int D> bool inside_box(const Vec<D>& x, const Vec3& lo, const Vec3& hi) {
  for (int k = 0; k < D; ++k)
    if (x[k] < lo[k] || x[k] > hi[k]) return false;
  return true;
}

template <int D>
Vec<D> initial_body_velocity(const BodySection& body, const Vec<D>& x) {
  Vec<D> v;
  for (int k = 0; k < D; ++k) v[k] = body.velocity[k];
  if (body.velocity_profile && *body.velocity_profile == "sin_x") {
    const double s = (x[0] - body.lower[0]) / (body.upper[0] - body.lower[0]);
    v *= std::sin(std::numbers::pi * s);
  }
  return v;
}

} // namespace

/// Cells of the grid spacing h that tile a body box along each axis.
template <int D> Index<D> body_cells(const BodySection& body, const Vec<D>& h) {
  Index<D> cells;
  for (int k = 0; k < D; ++k)
    cells[k] = std::max(1, static_cast<int>(std::lround((body.upper[k] - body.lower[k]) / h[k])));
  return cells;
}

/// The number of particles seed_particles creates.
template <int D> std::size_t seed_count(const Scene& scene, const Vec<D>& h) {
  std::size_t total = 0;
  for (const BodySection& body : scene.bodies) {
    std::size_t n = 1;
    const Index<D> cells = body_cells<D>(body, h);
    for (int k = 0; k < D; ++k) n *= static_cast<std::size_t>(cells[k]) * static_cast<std::size_t>(body.particles_per_cell);
    total += n;
  }
  return total;
}

template <int D> Particles<D> seed_particles(const Scene& scene, const Vec<D>& h) {
  validate_seeding<D>(scene, h);
  Particles<D> P;
  struct Seed { Vec<D> x, len; double V; int mat, body; };
  std::vector<Seed> seeds;
  seeds.reserve(seed_count<D>(scene, h)); // no growth by doubling: peak memory
  for (std::size_t b = 0; b < scene.bodies.size(); ++b) {
    const BodySection& body = scene.bodies[b];
    const int mat = material_index(scene, body);
    const int n = body.particles_per_cell;
    std::vector<double> s, w;
    cell_pattern(body.placement, n, s, w);
    const Index<D> cells = body_cells<D>(body, h);
    Vec<D> size;
    for (int k = 0; k < D; ++k) size[k] = (body.upper[k] - body.lower[k]) / cells[k];
    Index<D> c{};
    // Iterate cells (axis 0 fastest), then particles inside each cell.
    while (true) {
      Index<D> q{};
      while (true) {
        Seed sd;
        sd.V = 1.0;
        for (int k = 0; k < D; ++k) {
          sd.x[k] = body.lower[k] + (c[k] + s[q[k]]) * size[k];
          sd.V *= w[q[k]] * size[k];
          sd.len[k] = size[k] / n;
        }
        sd.mat = mat;
        sd.body = static_cast<int>(b);
        seeds.push_back(sd);
        int k = 0;
        while (k < D && ++q[k] == n) q[k++] = 0;
        if (k == D) break;
      }
      int k = 0;
      while (k < D && ++c[k] == cells[k]) c[k++] = 0;
      if (k == D) break;
    }
  }
  P.resize(static_cast<int>(seeds.size()));
  for (int p = 0; p < P.size(); ++p) {
    const Seed& sd = seeds[p];
    const MaterialSection& mat = scene.materials[sd.mat];
    const BodySection& body = scene.bodies[sd.body];
    P.x[p] = P.X[p] = sd.x;
    P.V[p] = P.V0[p] = sd.V;
    P.rho[p] = mat.density;
    P.m[p] = mat.density * sd.V;
    P.material[p] = sd.mat;
    P.body[p] = sd.body;
    P.length0[p] = sd.len;
    P.v[p] = initial_body_velocity<D>(body, sd.x);
    for (const InitialVelocitySection& iv : scene.initial_velocities)
      if (inside_box<D>(sd.x, iv.lower, iv.upper))
        for (int k = 0; k < D; ++k) P.v[p][k] = iv.velocity[k];
  }
  return P;
}

template struct Particles<1>;
template struct Particles<2>;
template struct Particles<3>;
template Particles<1> seed_particles<1>(const Scene&, const Vec<1>&);
template Particles<2> seed_particles<2>(const Scene&, const Vec<2>&);
template Particles<3> seed_particles<3>(const Scene&, const Vec<3>&);

} // namespace otmpm
