// The updated-Lagrangian side on large deformation: the F-bar patch average
// (engine/volumetric.hpp), nodes that follow the body, particle files on the
// scene grid's lines, and the rule for a material point whose max-ent support
// degenerates (a wider search, then a move into the hull, both counted).
#include <doctest/doctest.h>

#include "otmpm/assembly/assembler.hpp"
#include "otmpm/engine/volumetric.hpp"
#include "otmpm/integrators/integrator.hpp"
#include "otmpm/materials/material.hpp"
#include "otmpm/scene/scene_rules.hpp"
#include "support.hpp"
#include "temp_dir.hpp"

#include <array>
#include <cmath>
#include <fstream>
#include <random>
#include <string>

using namespace otmpm;
using otmpm::test::ScopedThreads;

namespace {

/// A random velocity-gradient increment H of size `scale`.
template <int D> Mat<D> random_H(std::mt19937& rng, double scale) {
  std::uniform_real_distribution<double> u(-scale, scale);
  Mat<D> H;
  for (int i = 0; i < D; ++i)
    for (int j = 0; j < D; ++j) H(i, j) = u(rng);
  return H;
}

/// det(I + H) and the isochoric part (I + H) / det(I + H)^(1/D).
template <int D> std::pair<double, Mat<D>> split(const Mat<D>& H) {
  const Mat<D> F = Mat<D>::Identity() + H;
  const double J = F.determinant();
  return {J, F / std::pow(J, 1.0 / D)};
}

template <int D> void check_patch_average() {
  CAPTURE(D);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> vol(0.5, 2.0);
  const int n = 12; // four patches of 3
  std::vector<long long> patch(n);
  std::vector<double> V(n);
  AlignedVector<Mat<D>> H(n), H0;
  for (int p = 0; p < n; ++p) {
    patch[static_cast<std::size_t>(p)] = p % 4 == 3 ? 7 : p % 3; // patches 0, 1, 2 and a patch 7 of three
    V[static_cast<std::size_t>(p)] = vol(rng);
    H[static_cast<std::size_t>(p)] = random_H<D>(rng, 0.05);
  }
  H0 = H;
  PatchAverage<D> average;
  average.apply(patch, 8, V.data(), H.data(), n);
  for (long long c : {0LL, 1LL, 2LL, 7LL}) {
    double sum_VJ = 0.0, sum_V = 0.0;
    for (int p = 0; p < n; ++p)
      if (patch[static_cast<std::size_t>(p)] == c) {
        sum_VJ += V[static_cast<std::size_t>(p)] * split<D>(H0[static_cast<std::size_t>(p)]).first;
        sum_V += V[static_cast<std::size_t>(p)];
      }
    for (int p = 0; p < n; ++p) {
      if (patch[static_cast<std::size_t>(p)] != c) continue;
      const auto [J0, iso0] = split<D>(H0[static_cast<std::size_t>(p)]);
      const auto [J, iso] = split<D>(H[static_cast<std::size_t>(p)]);
      // det dFbar is the patch's volume ratio; the isochoric part is the particle's own
      CHECK(J == doctest::Approx(sum_VJ / sum_V).epsilon(1e-14));
      CHECK((iso - iso0).norm() <= 1e-14);
    }
  }
}

/// One particle per patch: H unchanged, bit for bit.
template <int D> void check_single_particle_patches() {
  std::mt19937 rng(3);
  const int n = 5;
  std::vector<long long> patch{0, 1, 2, 3, 4};
  std::vector<double> V(n, 1.0);
  AlignedVector<Mat<D>> H(n);
  for (auto& h : H) h = random_H<D>(rng, 0.1);
  const AlignedVector<Mat<D>> H0 = H;
  PatchAverage<D> average;
  average.apply(patch, 5, V.data(), H.data(), n);
  for (int p = 0; p < n; ++p) CHECK(H[static_cast<std::size_t>(p)] == H0[static_cast<std::size_t>(p)]);
  // and its stress in the forces: no shift of the mean stress
  AlignedVector<Mat<D>> sigma(n);
  for (auto& s : sigma) s = random_H<D>(rng, 1e6);
  std::vector<double> shift(n, 1.0);
  average.shift_mean_stress(patch, 5, V.data(), sigma.data(), shift.data(), n);
  for (double s : shift) CHECK(s == 0.0);
}

/// A homogeneous deformation: every particle of a patch keeps its H to round-off.
template <int D> void check_homogeneous() {
  std::mt19937 rng(11);
  const Mat<D> h = random_H<D>(rng, 0.02);
  const int n = 9;
  std::vector<long long> patch(n, 0);
  std::vector<double> V{0.3, 1.0, 2.5, 0.7, 1.1, 0.9, 1.3, 0.2, 4.0};
  AlignedVector<Mat<D>> H(n, h);
  PatchAverage<D> average;
  average.apply(patch, 1, V.data(), H.data(), n);
  for (const Mat<D>& Hp : H) CHECK((Hp - h).cwiseAbs().maxCoeff() <= 4e-16 * (1.0 + h.cwiseAbs().maxCoeff()));
}

/// The treatments that average the volume change (scene_rules::kVolumetric without "none").
std::vector<std::string> averaging_treatments() {
  std::vector<std::string> out;
  for (std::string_view v : scene_rules::kVolumetric)
    if (v != "none") out.emplace_back(v);
  return out;
}

/// Nodal F-bar on a random 1D-in-index row table: each particle's row holds
/// `width` consecutive nodes with random positive weights summing to one.
template <int D> BasisTable<D> random_rows(std::mt19937& rng, int n, int nodes, int width) {
  std::uniform_real_distribution<double> u(0.1, 1.0);
  BasisTable<D> t;
  for (int p = 0; p < n; ++p) {
    const int first = static_cast<int>(rng() % static_cast<unsigned>(nodes - width + 1));
    double sum = 0.0;
    std::vector<double> w(static_cast<std::size_t>(width));
    for (double& x : w) sum += (x = u(rng));
    for (int k = 0; k < width; ++k) {
      t.node.push_back(first + k);
      t.N.push_back(w[static_cast<std::size_t>(k)] / sum);
      t.dN.push_back(Vec<D>::Zero());
    }
    t.offset.push_back(static_cast<int>(t.node.size()));
  }
  return t;
}

/// Nodal F-bar: dJbar_p = sum_I N_Ip dJ_I with dJ_I the N V weighted nodal
/// mean (volumetric.hpp), the isochoric part the particle's own; a
/// homogeneous deformation unchanged; the mean-stress shift the same operator.
template <int D> void check_nodal_average() {
  CAPTURE(D);
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> vol(0.5, 2.0);
  const int n = 40, nodes = 12;
  const BasisTable<D> t = random_rows<D>(rng, n, nodes, 4);
  std::vector<double> V(n);
  AlignedVector<Mat<D>> H(n), sigma(n);
  for (int p = 0; p < n; ++p) {
    V[static_cast<std::size_t>(p)] = vol(rng);
    H[static_cast<std::size_t>(p)] = random_H<D>(rng, 0.05);
    sigma[static_cast<std::size_t>(p)] = random_H<D>(rng, 1e6);
  }
  const AlignedVector<Mat<D>> H0 = H;
  NodalAverage<D> average;
  average.apply(t, nodes, V.data(), H.data(), n);
  // the definition, summed here independently
  const auto smoothed = [&](const auto& value) {
    std::vector<double> num(nodes, 0.0), den(nodes, 0.0), out(n, 0.0);
    for (int p = 0; p < n; ++p)
      for (int e = t.begin(p); e < t.end(p); ++e) {
        num[static_cast<std::size_t>(t.node[e])] += t.N[e] * V[static_cast<std::size_t>(p)] * value(p);
        den[static_cast<std::size_t>(t.node[e])] += t.N[e] * V[static_cast<std::size_t>(p)];
      }
    for (int p = 0; p < n; ++p)
      for (int e = t.begin(p); e < t.end(p); ++e)
        out[static_cast<std::size_t>(p)] +=
            t.N[e] * num[static_cast<std::size_t>(t.node[e])] / den[static_cast<std::size_t>(t.node[e])];
    return out;
  };
  const std::vector<double> Jbar =
      smoothed([&](int p) { return split<D>(H0[static_cast<std::size_t>(p)]).first; });
  double spread = 0.0; // the average must change the volume ratios: a test that cannot fail otherwise
  for (int p = 0; p < n; ++p) {
    const auto [J0, iso0] = split<D>(H0[static_cast<std::size_t>(p)]);
    const auto [J, iso] = split<D>(H[static_cast<std::size_t>(p)]);
    CHECK(J == doctest::Approx(Jbar[static_cast<std::size_t>(p)]).epsilon(1e-13));
    CHECK((iso - iso0).norm() <= 1e-14);
    spread = std::max(spread, std::abs(J - J0));
  }
  CHECK(spread > 1e-3);
  std::vector<double> shift(n);
  average.shift_mean_stress(t, nodes, V.data(), sigma.data(), shift.data(), n);
  const std::vector<double> mbar =
      smoothed([&](int p) { return sigma[static_cast<std::size_t>(p)].trace() / D; });
  for (int p = 0; p < n; ++p)
    CHECK(shift[static_cast<std::size_t>(p)] + sigma[static_cast<std::size_t>(p)].trace() / D ==
          doctest::Approx(mbar[static_cast<std::size_t>(p)]).epsilon(1e-13).scale(1e6));
  // a homogeneous deformation: H unchanged to round-off
  const Mat<D> h = random_H<D>(rng, 0.02);
  AlignedVector<Mat<D>> Hh(n, h);
  average.apply(t, nodes, V.data(), Hh.data(), n);
  for (const Mat<D>& Hp : Hh)
    CHECK((Hp - h).cwiseAbs().maxCoeff() <= 4e-16 * (1.0 + h.cwiseAbs().maxCoeff()));
}

/// A 2D ul scene of a j2 block (20 x 10 cells of 0.05 m) with `extra` TOML.
std::string block_scene(const std::string& extra) {
  return R"(
[simulation]
dimension = 2
mode = "ul"
integrator = "npc"
t_end = 0.01
cfl = 0.3
[basis]
kind = "linear"
[grid]
lower = [0.0, 0.0]
upper = [1.0, 0.5]
cells = [20, 10]
[[material]]
name = "m"
model = "j2"
density = 1000.0
young = 1.0e7
poisson = 0.45
yield_stress = 1.0e5
hardening_modulus = 0.0
[output]
every = 0.0
)" + extra;
}

} // namespace

TEST_CASE("F-bar: det dFbar is the patch's volume ratio, the isochoric part the particle's own (2D, 3D)") {
  check_patch_average<2>();
  check_patch_average<3>();
}

TEST_CASE("F-bar: a patch of one particle keeps its dF bit for bit, 1D is unchanged") {
  check_single_particle_patches<2>();
  check_single_particle_patches<3>();
  check_single_particle_patches<1>(); // one axis: no volumetric part to average
}

TEST_CASE("F-bar reduces to F for a homogeneous deformation") {
  check_homogeneous<2>();
  check_homogeneous<3>();
}

TEST_CASE("nodal F-bar: det dFbar is the nodal average interpolated back, the forces' mean stress the same "
          "(2D, 3D)") {
  check_nodal_average<2>();
  check_nodal_average<3>();
}

TEST_CASE("F-bar in the engine: a homogeneous stretch gives the same F with and without the average") {
  // Every node moves with v = v0 + L x: every particle's velocity gradient
  // is L, so the patch average changes nothing but round-off - with every
  // integrator of the table (each reaches the average by its own stage).
  for (const IntegratorKind& kind : integrator_kinds()) {
    const std::string integrator(kind.name);
    CAPTURE(integrator);
    const auto stretched = [&](const std::string& volumetric) {
      Scene s = parse_scene(
          block_scene(R"(
[[body]]
name = "b"
material = "m"
lower = [0.0, 0.0]
upper = [1.0, 0.5]
velocity = [1.0, 0.0]
)"),
          "stretch.toml",
          {"simulation.integrator=\"" + integrator + "\"", "simulation.volumetric=\"" + volumetric + "\"",
           std::string("basis.kind=\"") + (kind.needs_bspline ? "bspline2" : "linear") + "\""});
      Engine<2> e = assemble<2>(s);
      Mat<2> L;
      L << 0.3, 0.1, -0.05, -0.2;
      for (int p = 0; p < e.particles().size(); ++p) e.particles().v[p] += L * e.particles().x[p];
      e.step();
      return std::pair{e.particles().F, e.particles().X};
    };
    const auto [own, X] = stretched("none");
    for (const std::string& volumetric : averaging_treatments()) {
      CAPTURE(volumetric);
      const AlignedVector<Mat<2>> F = stretched(volumetric).first;
      REQUIRE(F.size() == own.size());
      // The nodes of the block's edge take the mean velocity of particles on
      // one side (v at their mean position, inside): the cells along the edge
      // stretch a little less than L, each uniformly. A cell patch sees one
      // such cell; the nodal average also reaches 2 cells (h = 0.05) beyond a
      // particle's own, so it is compared 3 cells inside the edge.
      const double inside = volumetric == "fbar_nodal" ? 0.15 : 0.0;
      double worst = 0.0;
      int compared = 0;
      for (std::size_t p = 0; p < F.size(); ++p) {
        if (std::min({X[p][0], 1.0 - X[p][0], X[p][1], 0.5 - X[p][1]}) < inside) continue;
        worst = std::max(worst, (F[p] - own[p]).cwiseAbs().maxCoeff());
        ++compared;
      }
      CHECK(compared >= 100);
      CHECK(worst <= 1e-14);
    }
  }
}

TEST_CASE("F-bar: the internal forces' power is the rate of the energy the averaged rate stores") {
  // Non-uniform stress (its mean varies inside every cell) and a nodal
  // velocity that is not affine. The power of the nodal forces, sum_I f_I .
  // v_I, must be -sum_p V_p sigma_p : Lbar_p, with Lbar_p the averaged rate
  // the materials receive: (F_p(+e) - F_p(-e)) / 2e after one update with
  // H = +-e L_p from F = I. The forces of sigma_p itself miss it.
  // (both vary on the scale of a cell, h = 0.05)
  const auto velocity = [](const Vec<2>& x) {
    return Vec<2>(std::sin(40.0 * x[0]) + x[1] * x[1], x[0] * x[1] - std::cos(50.0 * x[1] + 20.0 * x[0]));
  };
  const auto stress = [](const Vec<2>& x) {
    Mat<2> s;
    s << -1e5 * (2.0 + std::sin(70.0 * x[0] + 50.0 * x[1])), 3e4 * x[0], 3e4 * x[0], -2e5 * (1.0 - 5.0 * x[1] * x[0]);
    return s;
  };
  const double e = 1e-7;
  std::vector<std::array<std::string, 3>> settings; // mode, basis, treatment
  for (const std::string& volumetric : averaging_treatments())
    for (const auto& [mode, basis] :
         {std::pair{"ul", "linear"}, {"mpm", "linear"}, {"mpm", "lme"}, {"ul", "lme"}})
      settings.push_back({mode, basis, volumetric});
  for (const auto& [mode, basis, volumetric] : settings) {
    const std::string setting = std::string(mode) + ", " + basis + ", " + volumetric;
    CAPTURE(setting);
    const Scene s = parse_scene(block_scene(R"(
[[body]]
name = "b"
material = "m"
lower = [0.2, 0.1]
upper = [0.8, 0.4]
)"),
                                "power.toml",
                                {std::string("simulation.mode=\"") + mode + "\"",
                                 "simulation.volumetric=\"" + volumetric + "\"",
                                 std::string("basis.kind=\"") + basis + "\""});
    const auto prepared = [&](AlignedVector<Vec<2>>& v) {
      Engine<2> engine = assemble<2>(s);
      engine.evaluate_basis();
      Particles<2>& P = engine.particles();
      for (int p = 0; p < P.size(); ++p) P.sigma[p] = stress(P.x[p]);
      v.resize(engine.basis().nodes().positions().size());
      for (std::size_t I = 0; I < v.size(); ++I) v[I] = velocity(engine.basis().nodes().position(static_cast<int>(I)));
      return engine;
    };
    AlignedVector<Vec<2>> v;
    Engine<2> forces = prepared(v);
    const Particles<2> P = forces.particles(); // V_p and sigma_p of the forces
    forces.to_nodes({.forces = true});
    double power = 0.0, power_own = 0.0, scale = 0.0;
    for (std::size_t I = 0; I < v.size(); ++I) power += forces.nodal().f[I].dot(v[I]);
    const BasisTable<2>& table = forces.table();
    AlignedVector<Mat<2>> F[2];
    for (int k = 0; k < 2; ++k) {
      Engine<2> moved = prepared(v);
      REQUIRE_FALSE(moved.particles().F.empty());
      moved.update_stress({&v, k == 0 ? e : -e});
      F[k] = moved.particles().F;
    }
    double stored = 0.0;
    for (int p = 0; p < P.size(); ++p) {
      Mat<2> L = Mat<2>::Zero();
      for (int i = table.begin(p); i < table.end(p); ++i) L += v[table.node[i]] * table.dN[i].transpose();
      const Mat<2> Lbar = (F[0][p] - F[1][p]) / (2.0 * e);
      stored += P.V[p] * P.sigma[p].cwiseProduct(Lbar).sum();
      power_own -= P.V[p] * P.sigma[p].cwiseProduct(L).sum();
      scale += P.V[p] * P.sigma[p].norm() * L.norm();
    }
    CAPTURE(power);
    CAPTURE(stored);
    CAPTURE(power_own);
    CAPTURE(scale);
    // the central difference's error ((e |L|)^2 ~ 1e-11 with |L| ~ 50) and round-off in F (1e-16 / e |L|)
    CHECK(std::abs(power + stored) <= 1e-9 * scale);
    CHECK(std::abs(power_own + stored) >= 1e-3 * scale); // the stress's own mean is not conjugate
  }
}

TEST_CASE("simulation.volumetric: by default fbar in ul with a plastic material that is not frictional, else none, bad values refused") {
  const std::string body = R"(
[[body]]
name = "b"
material = "m"
lower = [0.0, 0.0]
upper = [1.0, 0.5]
)";
  CHECK(volumetric_treatment(parse_scene(block_scene(body), "a.toml")) == "fbar"); // ul, j2
  CHECK(volumetric_treatment(parse_scene(block_scene(body), "a.toml", {"simulation.mode=\"mpm\""})) == "none");
  Scene elastic = parse_scene(block_scene(body), "a.toml");
  elastic.materials.front().model = "neo_hookean";
  elastic.materials.front().extra.clear();
  CHECK(volumetric_treatment(elastic) == "none"); // elastic: no locking to treat
  // over the model table: fbar in ul for the plastic models whose cone does
  // not depend on the pressure, none for elastic and frictional ones
  for (const MaterialModel* m : material_models()) {
    CAPTURE(m->name);
    Scene s = elastic;
    s.materials.front().model = std::string(m->name);
    CHECK(volumetric_treatment(s) == (!m->state.empty() && !m->frictional ? "fbar" : "none"));
  }
  CHECK(find_material_model("drucker_prager")->frictional);
  CHECK(find_material_model("mu_i")->frictional);
  CHECK_FALSE(find_material_model("j2")->frictional);
  CHECK(volumetric_treatment(parse_scene(block_scene(body), "a.toml",
                                         {"simulation.mode=\"mpm\"", "simulation.volumetric=\"fbar\""})) == "fbar");
  CHECK(volumetric_treatment(parse_scene(block_scene(body), "a.toml",
                                         {"simulation.volumetric=\"fbar_nodal\""})) == "fbar_nodal");
  CHECK_THROWS_WITH_AS(parse_scene(block_scene(body), "a.toml", {"simulation.volumetric=\"bar\""}),
                       doctest::Contains("volumetric"), InputError);
  Scene s = parse_scene(block_scene(body), "a.toml");
  s.simulation.volumetric = "fbar ";
  CHECK_THROWS_AS(assemble<2>(s), InputError);
  // the scene written back says what ran
  const std::string text = to_toml(parse_scene(block_scene(body), "a.toml"));
  CAPTURE(text);
  CHECK(text.find("volumetric = 'fbar'") != std::string::npos);
}

TEST_CASE("F-bar: results are bitwise identical with 1 and 2 threads (ul, j2, npc and fe, each averaging "
          "treatment)") {
  // 3200 particles, a block pressed onto its base: plastic in the rows there
  std::vector<std::pair<std::string, std::string>> settings; // treatment, integrator
  for (const std::string& volumetric : averaging_treatments())
    for (const char* integrator : {"npc", "fe"}) settings.emplace_back(volumetric, integrator);
  for (const auto& [volumetric, integrator] : settings) {
    CAPTURE(volumetric);
    CAPTURE(integrator);
    Particles<2> P[2];
    for (int threads = 1; threads <= 2; ++threads) {
      const ScopedThreads scope(threads);
      Scene s = parse_scene(block_scene(R"(
[[body]]
name = "b"
material = "m"
lower = [0.0, 0.0]
upper = [1.0, 0.5]
velocity = [0.3, -2.0]
particles_per_cell = 4
[[boundary]]
name = "base"
lower = [0.0, 0.0]
upper = [1.0, 0.0]
fix = [true, true]
)"),
                            "fbar.toml",
                            {std::string("simulation.integrator=\"") + integrator + "\"",
                             "simulation.volumetric=\"" + volumetric + "\""});
      Engine<2> e = assemble<2>(s);
      for (int k = 0; k < 8; ++k) e.step();
      P[threads - 1] = e.particles();
    }
    bool same = true;
    for (int p = 0; p < P[0].size(); ++p)
      same = same && P[0].x[p] == P[1].x[p] && P[0].v[p] == P[1].v[p] && P[0].sigma[p] == P[1].sigma[p] &&
             P[0].F[p] == P[1].F[p];
    CHECK(same);
    const StateField* eps = P[0].find_state("plastic_strain");
    REQUIRE(eps != nullptr);
    CHECK(*std::max_element(eps->values.begin(), eps->values.end()) > 0.0); // the average met plastic flow
  }
}

TEST_CASE("ul: the nodes of lattice cells without particles leave the max-ent node set") {
  // A disk in the box of its bounds: the corner cells hold no particle.
  const std::string disk = block_scene(R"(
[[body]]
name = "disk"
material = "m"
shape = "sphere"
center = [0.5, 0.25]
radius = 0.2
)");
  Scene s = parse_scene(disk, "disk.toml", {"basis.kind=\"lme\""});
  Engine<2> e = assemble<2>(s);
  const NodeSet<2>& nodes = e.basis().nodes();
  REQUIRE(nodes.grid().has_value());
  CHECK(nodes.has_absent());
  CHECK(nodes.present_count() < nodes.size());
  // a present node is a corner of a cell that holds a particle, an absent one is not
  const CartesianGrid<2>& g = *nodes.grid();
  std::vector<char> corner(static_cast<std::size_t>(nodes.size()), 0);
  for (int p = 0; p < e.particles().size(); ++p) {
    const Index<2> c = g.cell_of(e.particles().X[p]);
    for (int i = 0; i < 2; ++i)
      for (int j = 0; j < 2; ++j) corner[static_cast<std::size_t>(g.node_id({c[0] + i, c[1] + j}))] = 1;
  }
  for (int I = 0; I < nodes.size(); ++I) CHECK(nodes.present(I) == (corner[static_cast<std::size_t>(I)] != 0));
  // no search finds an absent node
  std::vector<int> found;
  nodes.within(nodes.position(0), 10.0, found);
  CHECK(static_cast<int>(found.size()) == nodes.present_count());
  for (int I : found) CHECK(nodes.present(I));
  // the linear basis keeps the whole lattice (its cells are its elements)
  Engine<2> linear = assemble<2>(parse_scene(disk, "disk.toml"));
  CHECK_FALSE(linear.basis().nodes().has_absent());
}

TEST_CASE("ul: a particle file's node lattice runs on the scene grid's lines, every particle strictly inside") {
  // particles at sub-cell centres of a grid from 0 (h = 0.1), of extent 0.05: the
  // file's bounds are 0.1 .. 0.3 across and along x up to the last one's 0.525
  otmpm::test::TempDir dir("volumetric_file");
  {
    std::ofstream f(dir.file("p.csv"));
    f << "x,y,volume\n";
    for (int i = 0; i < 4; ++i)
      for (int j = 0; j < 4; ++j) f << 0.125 + 0.05 * i << "," << 0.125 + 0.05 * j << ",0.0025\n";
    f << "0.5,0.2,0.0025\n";
  }
  const std::string scene = block_scene(R"(
[[body]]
name = "f"
material = "m"
shape = "file"
file = "p.csv"
)");
  {
    std::ofstream f(dir.file("s.toml"));
    f << scene;
  }
  const Scene s = load_scene(dir.file("s.toml"), {"grid.cells=[10, 5]"});
  const LatticeBox box = node_lattice_box(s);
  // the bounds on lines stay there; 0.525 is rounded out to 0.6
  CHECK(box.lower[0] == doctest::Approx(0.1));
  CHECK(box.upper[0] == doctest::Approx(0.6));
  CHECK(box.cells[0] == doctest::Approx(5.0));
  CHECK(box.lower[1] == doctest::Approx(0.1));
  CHECK(box.upper[1] == doctest::Approx(0.3));
}

TEST_CASE("lme: a point outside the hull of its cut-off support is carried by a wider search, counted") {
  // Nodes on a line y = 0 and one node 2.5 h above: a point just above the
  // line sees only the line within the cut-off (1.86 h), the node above
  // only in the search twice as wide.
  AlignedVector<Vec<2>> x;
  for (int i = 0; i <= 10; ++i) x.push_back(Vec<2>(0.1 * i, 0.0));
  x.push_back(Vec<2>(0.5, 0.25));
  BasisOptions opt;
  opt.kind = "lme";
  opt.values["gamma_lme"] = 4.0;
  auto basis = make_basis<2>(opt, NodeSet<2>::cloud(x, 0.1));
  PointQuery<2> q;
  q.x = Vec<2>(0.5, 0.02);
  Stencil<2> st;
  basis->evaluate(q, st);
  CHECK(basis->widened_supports() == 1);
  double sum = 0.0;
  Vec<2> xbar = Vec<2>::Zero();
  for (int i = 0; i < st.size(); ++i) sum += st.N[static_cast<std::size_t>(i)], xbar += st.N[static_cast<std::size_t>(i)] * x[static_cast<std::size_t>(st.node[static_cast<std::size_t>(i)])];
  CHECK(sum == doctest::Approx(1.0).epsilon(1e-12));
  CHECK((xbar - q.x).norm() <= 1e-10);
}

TEST_CASE("lme: a point outside the hull of every node near it is moved into it when the caller allows, counted") {
  AlignedVector<Vec<2>> x;
  for (int i = 0; i <= 4; ++i)
    for (int j = 0; j <= 4; ++j) x.push_back(Vec<2>(0.1 * i, 0.1 * j));
  BasisOptions opt;
  opt.kind = "lme";
  auto basis = make_basis<2>(opt, NodeSet<2>::cloud(x, 0.1));
  PointQuery<2> q;
  q.x = Vec<2>(0.2, -0.03); // below the lowest row
  Stencil<2> st;
  CHECK_THROWS_AS(basis->evaluate(q, st), BasisError); // no `moved`: the point fails as before
  Vec<2> moved = Vec<2>::Zero();
  Vec<2> lambda = Vec<2>::Zero();
  q.moved = &moved;
  q.lambda = &lambda;
  basis->evaluate(q, st);
  CHECK(basis->moved_points() == 1);
  const Vec<2> y = q.x + moved;
  CHECK(y[1] >= 0.0);
  CHECK(y[1] <= 0.02);                                 // to the hull, within the bisection's resolution
  CHECK(std::abs(y[0] - 0.2) <= 1e-12);                // towards the centroid (0.2, 0.2): straight up
  Vec<2> xbar = Vec<2>::Zero();
  for (int i = 0; i < st.size(); ++i) xbar += st.N[static_cast<std::size_t>(i)] * x[static_cast<std::size_t>(st.node[static_cast<std::size_t>(i)])];
  CHECK((xbar - y).norm() <= 1e-10); // the row is that of the moved position
}
