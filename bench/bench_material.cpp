// bench_material: nanoseconds per material-point update, one core.
//
//   build/bench/bench_material [--points N] [--repeat R] [--case SUBSTRING]
//
// Each case runs the constitutive work of one particle as the engine would do
// it for that model, over N points (fixed seed), timed once per repetition:
//  - neo_hookean:   F <- dF F; sigma = neo_hookean_stress<D>(F)   (materials/elasticity.hpp)
//  - j2, drucker_prager (hencky_plasticity.hpp):
//                   F <- dF F; tau = *_update<D>(dF, state); sigma = tau / det F
//  - "material ...": the same points through the engine's batch update,
//                   Material<D>::update (j2: plane strain and 3D two
//                   particles per register), against neo_hookean's
// "elastic": every point stays inside the yield surface; "plastic": every
// point is in plastic flow (states driven onto the yield surface first, dF
// continuing the same strain path). j2 johnson-cook adds the Newton return
// (B, n, C > 0, rate hardening active). 2D is plane strain, 3D general.
// States are restored (untimed) before each repetition, so every repetition
// does the same work; the cases run interleaved (one repetition of each in
// turn) so that drift of the machine's speed hits them alike. Times are the
// thread's CPU time (CLOCK_THREAD_CPUTIME_ID), so that time the thread spends
// descheduled on a shared machine does not count. Prints the median over R
// repetitions and the ratio to neo_hookean of the same dimension.
#include "otmpm/openmp_wait.hpp"
#include "bench_util.hpp"
#include "otmpm/materials/hencky_plasticity.hpp"
#include "otmpm/materials/elasticity.hpp"
#include "otmpm/materials/material.hpp"

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <functional>
#include <map>
#include <memory>
#include <random>
#include <string>
#include <vector>

using namespace otmpm;
using namespace otmpm::plasticity;
using otmpm::bench::median;
using otmpm::bench::thread_ns;

namespace {

/// One benchmark case: `reset` restores the inputs (untimed), `run` does the
/// N point updates and returns a checksum (keeps the work alive).
struct Case {
  std::string label;
  int dim;
  std::function<void()> reset;
  std::function<double()> run;
  std::vector<double> ns;
};

/// I + H with random entries of H in [-size, size]; `isochoric`: tr H = 0
/// (shear paths that keep a pressure-dependent material on its yield surface).
template <int D> Mat<D> random_increment(std::mt19937_64& rng, double size, bool isochoric = false) {
  std::uniform_real_distribution<double> u(-size, size);
  Mat<D> H;
  for (int i = 0; i < D; ++i)
    for (int j = 0; j < D; ++j) H(i, j) = u(rng);
  if (isochoric) H -= H.trace() / D * Mat<D>::Identity().eval();
  return Mat<D>::Identity() + H;
}

/// Points of one case: increments, deformation gradients and states.
template <int D> struct Points {
  AlignedVector<Mat<D>> dF, F, F0;
  std::vector<HenckyState> state, state0;
  AlignedVector<Mat<D>> sigma;
};

/// Drives each point along its own increment until `plastic(update)` holds
/// (or for a fixed number of steps when elastic), recording the start state.
template <int D, class Step>
Points<D> prepare(int n, std::mt19937_64& rng, double size, bool plastic, const Step& step, const Mat3& be0) {
  Points<D> p;
  p.dF.resize(n);
  p.F0.assign(n, Mat<D>::Identity());
  p.state0.resize(n);
  for (int i = 0; i < n; ++i) {
    p.state0[i].be = be0;
    p.dF[i] = random_increment<D>(rng, size, plastic);
    if (plastic) {
      // Load along dF until the point has flowed plastically in 3 steps in a row.
      for (int k = 0, run = 0; k < 10000 && run < 3; ++k) {
        p.F0[i] = p.dF[i] * p.F0[i];
        run = step(p.dF[i], p.state0[i]).plastic ? run + 1 : 0;
      }
    } else {
      for (int k = 0; k < 3; ++k) {
        p.F0[i] = p.dF[i] * p.F0[i];
        step(p.dF[i], p.state0[i]);
      }
    }
  }
  p.F = p.F0;
  p.state = p.state0;
  p.sigma.resize(n);
  return p;
}

template <int D> Mat<D> cauchy_from(const Mat3& tau, const Mat<D>& F) {
  return tau.topLeftCorner<D, D>() / F.determinant();
}

/// Cases whose label does not contain this are not prepared (--case).
std::string g_only;

template <int D, class Step>
void add_plastic_case(std::vector<Case>& cases, const std::string& label, int n, std::mt19937_64& rng, double size,
                      bool plastic, Step step, bool expect_plastic, const Mat3& be0 = Mat3::Identity()) {
  if (label.find(g_only) == std::string::npos) return;
  auto pts = std::make_shared<Points<D>>(prepare<D>(n, rng, size, plastic, step, be0));
  // Check what the case measures: every point elastic or every point plastic.
  {
    Points<D> probe = *pts;
    int count = 0;
    for (int i = 0; i < n; ++i) count += step(probe.dF[i], probe.state[i]).plastic;
    if (count != (expect_plastic ? n : 0))
      std::fprintf(stderr, "bench_material: case %s has %d of %d points plastic\n", label.c_str(), count, n);
  }
  cases.push_back({label, D,
                   [pts] {
                     pts->F = pts->F0;
                     pts->state = pts->state0;
                   },
                   [pts, step, n] {
                     double sum = 0.0;
                     for (int i = 0; i < n; ++i) {
                       pts->F[i] = pts->dF[i] * pts->F[i];
                       const PointUpdate u = step(pts->dF[i], pts->state[i]);
                       pts->sigma[i] = cauchy_from<D>(u.kirchhoff, pts->F[i]);
                       sum += pts->sigma[i](0, 0);
                     }
                     return sum;
                   },
                   {}});
}

/// A case through the engine's batch update (Material<D>::update over all
/// points, H = dF - I): `model` with `keys`, the points' F and b_e, eps_p
/// from `pts` (neo_hookean: F only).
template <int D>
void add_material_case(std::vector<Case>& cases, const std::string& label, const std::string& model,
                       std::map<std::string, double> keys, std::shared_ptr<Points<D>> pts) {
  if (label.find(g_only) == std::string::npos && model != "neo_hookean") return;
  struct Batch {
    std::unique_ptr<Material<D>> material;
    Particles<D> P, P0;
    AlignedVector<Mat<D>> H;
  };
  auto b = std::make_shared<Batch>();
  b->material = make_material<D>({.name = "m", .model = model, .density = 1.0, .young = 200e9, .poisson = 0.3,
                                  .extra = std::move(keys)});
  const int n = static_cast<int>(pts->dF.size());
  b->P.resize(n);
  b->P.allocate_optional(false, true);
  for (const StateSpec& st : b->material->state()) b->P.add_state(std::string(st.name), st.width, st.initial.data());
  b->material->bind(b->P);
  StateField* be = b->P.find_state("elastic_left_cauchy_green");
  StateField* eps_p = b->P.find_state("plastic_strain");
  for (int i = 0; i < n; ++i) {
    b->P.V[i] = b->P.V0[i] = b->P.m[i] = b->P.rho[i] = 1.0;
    b->P.F[i] = pts->F0[i];
    b->H.push_back(pts->dF[i] - Mat<D>::Identity());
    if (be == nullptr) continue;
    const Mat3& s = pts->state0[i].be;
    const double v[6] = {s(0, 0), s(1, 1), s(2, 2), s(0, 1), s(1, 2), s(0, 2)};
    std::copy(v, v + 6, be->row(i));
    eps_p->values[static_cast<std::size_t>(i)] = pts->state0[i].eps_p;
  }
  b->P0 = b->P;
  cases.push_back({label, D, [b] { b->P = b->P0; },
                   [b, n] {
                     b->material->update(b->P, 0, n, b->H.data(), 1e-6);
                     return b->P.sigma[0](0, 0) + b->P.sigma[n - 1](0, 0);
                   },
                   {}});
}

template <int D> void add_cases(std::vector<Case>& cases, int n, std::mt19937_64& rng) {
  const std::string dim = std::to_string(D) + "D ";
  // Neo-Hookean with the same elastic constants as j2.
  const ElasticConstants nh{1.0, 200e9, 0.3};
  {
    auto pts = std::make_shared<Points<D>>();
    pts->dF.resize(n);
    pts->F0.resize(n);
    for (int i = 0; i < n; ++i) {
      pts->dF[i] = random_increment<D>(rng, 1e-4);
      pts->F0[i] = random_increment<D>(rng, 1e-3);
    }
    pts->F = pts->F0;
    pts->sigma.resize(n);
    cases.push_back({dim + "neo_hookean", D, [pts] { pts->F = pts->F0; },
                     [pts, nh, n] {
                       double sum = 0.0;
                       for (int i = 0; i < n; ++i) {
                         pts->F[i] = pts->dF[i] * pts->F[i];
                         pts->sigma[i] = neo_hookean_stress<D>(nh, pts->F[i]);
                         sum += pts->sigma[i](0, 0);
                       }
                       return sum;
                     },
                     {}});
  }
  J2Parameters j2;
  j2.elastic = ElasticModuli::from_young_poisson(200e9, 0.3);
  j2.yield_stress = 300e6;
  j2.hardening_modulus = 2e9;
  j2.validate();
  auto j2_step = [j2](const Mat<D>& dF, HenckyState& s) { return j2_update<D>(j2, dF, 1e-6, s); };
  // Elastic: 3 steps of 1e-4 from the reference state (q ~ 0.2 sigma_y).
  add_plastic_case<D>(cases, dim + "j2 elastic", n, rng, 1e-4, false, j2_step, false);
  add_plastic_case<D>(cases, dim + "j2 plastic", n, rng, 1e-3, true, j2_step, true);
  // The same through Material<D>::update (plane strain and 3D: two particles per register).
  if (D > 1 && (dim + "material").find(g_only) != std::string::npos) {
    auto elastic = std::make_shared<Points<D>>(prepare<D>(n, rng, 1e-4, false, j2_step, Mat3::Identity()));
    auto plastic = std::make_shared<Points<D>>(prepare<D>(n, rng, 1e-3, true, j2_step, Mat3::Identity()));
    add_material_case<D>(cases, dim + "material neo_hookean", "neo_hookean", {}, elastic);
    const std::map<std::string, double> keys{{"yield_stress", j2.yield_stress}, {"hardening_modulus", j2.hardening_modulus}};
    add_material_case<D>(cases, dim + "material j2 elastic", "j2", keys, elastic);
    add_material_case<D>(cases, dim + "material j2 plastic", "j2", keys, plastic);
  }
  J2Parameters jc = j2;
  jc.johnson_cook = JohnsonCook{500e6, 0.3, 0.02, 1.0};
  jc.validate();
  auto jc_step = [jc](const Mat<D>& dF, HenckyState& s) { return j2_update<D>(jc, dF, 1e-6, s); };
  add_plastic_case<D>(cases, dim + "j2 johnson-cook plastic", n, rng, 1e-3, true, jc_step, true);
  DruckerPragerParameters dp;
  dp.elastic = ElasticModuli::from_young_poisson(10e6, 0.3);
  dp.friction_angle = 30.0;
  dp.dilation_angle = 5.0;
  dp.cohesion = 20e3;
  dp.tension_cutoff = 10e3;
  const DruckerPrager dpm(dp);
  auto dp_step = [dpm](const Mat<D>& dF, HenckyState& s) { return drucker_prager_update<D>(dpm, dF, s); };
  // Isotropic pre-compression p0 = -50 kPa (b_e = exp(2 p0 / (3 K)) I), then
  // small increments (elastic) or isochoric shear into plastic flow.
  const Mat3 be0 = std::exp(2.0 * -50e3 / (3.0 * dp.elastic.bulk)) * Mat3::Identity();
  add_plastic_case<D>(cases, dim + "drucker_prager elastic", n, rng, 1e-4, false, dp_step, false, be0);
  add_plastic_case<D>(cases, dim + "drucker_prager plastic", n, rng, 1e-3, true, dp_step, true, be0);
}

} // namespace

int main(int argc, char** argv) {
  otmpm::default_openmp_wait(argv); // as the otmpm command waits (openmp_wait.hpp)
  int points = 20000, repeat = 21;
  for (int i = 1; i + 1 < argc; i += 2) {
    if (!std::strcmp(argv[i], "--points")) points = std::atoi(argv[i + 1]);
    if (!std::strcmp(argv[i], "--repeat")) repeat = std::atoi(argv[i + 1]);
    if (!std::strcmp(argv[i], "--case")) g_only = argv[i + 1]; // only these cases (and neo_hookean)
  }
  std::mt19937_64 rng(42);
  std::vector<Case> cases;
  add_cases<2>(cases, points, rng);
  add_cases<3>(cases, points, rng);
  double checksum = 0.0;
  for (int r = 0; r < repeat; ++r) {
    for (Case& c : cases) {
      c.reset();
      const double t0 = thread_ns();
      checksum += c.run();
      c.ns.push_back((thread_ns() - t0) / points);
    }
  }
  std::printf("%-34s %10s %14s\n", "case (one point update)", "ns/point", "/ neo_hookean");
  // Each case against neo_hookean of its dimension, the batch cases against the batch neo_hookean.
  const auto reference = [&](const Case& c) {
    const bool batch = c.label.find("material") != std::string::npos;
    for (const Case& r : cases)
      if (r.dim == c.dim && r.label.find("neo_hookean") != std::string::npos &&
          (r.label.find("material") != std::string::npos) == batch)
        return median(r.ns);
    return 0.0;
  };
  for (const Case& c : cases) std::printf("%-34s %10.1f %14.2f\n", c.label.c_str(), median(c.ns), median(c.ns) / reference(c));
  std::printf("(%d points, median of %d repetitions; checksum %.6e)\n", points, repeat, checksum);
  return 0;
}
