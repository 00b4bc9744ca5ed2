// bench_one_pass: how fast the 2D linear `fe` step of the benchmark block
// could run as ONE sweep over the particles (docs/performance.md, "Against
// the machine": the bound of a one-pass step).
//
//   OMP_NUM_THREADS=1 build/bench/bench_one_pass [--cells N] [--steps S] [--repeat R] [--check C]
//       [--engine 0] [--batch 1|32] [--lanes 1|4]
//
// OnePassBlock below is a model of the step, not a part of the library: the
// physics of step_fe (wobbes et al. Algorithm 1, lumped mass) with
// linear_elastic on the block of bench_step (N x N cells, 2 x 2 particles per
// cell, its base held), written as the fused grid-to-particle-to-grid sweep
// of the massively parallel MPM literature - the nodal update, then for each
// particle the grid-to-particle update, the stress update, the energy sums
// and checks, and the next step's particle-to-node sums, the weights of the
// linear hats recomputed from x_p in the sweep (no basis table), on one
// thread, scattering straight into the nodes. It leaves out what the engine
// needs beyond that block (other bases, integrators, threads, walls,
// deterministic blocked sums, the straight-path strain energy), so its rate
// bounds from above what fusing the engine's passes can give on this core.
// --batch 32 takes the sweep's three stages (grid-to-particle, stress and
// sums, particle-to-grid) a batch of 32 particles at a time, each stage a
// loop of its own over the batch; --batch 1 (the default) takes each
// particle through all three before the next. --lanes 4 (with --batch 32,
// on a core with AVX2) runs the batched sweep four particles per instruction
// (sweep_lanes), with the scalar sweep's bits: it checks that too.
//
// It first proves that it computes the engine's step: from the engine's
// initial particles and with the engine's time steps, its velocities and
// positions after --check steps agree with the engine's to kAgreement of
// their scale (exit 1 otherwise). Then it times itself and the engine on
// the same block, in turn (--repeat rounds), and prints both medians
// (--engine 0: the model alone, after the check - for counting its
// instructions and bytes with cachegrind, scripts/roofline.sh's way).
#include "bench_run.hpp"
#include "bench_scenes.hpp"
#include "otmpm/materials/hencky_solid_j2.hpp"
#include "otmpm/openmp_wait.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

using namespace otmpm;
using namespace otmpm::bench;

namespace {

/// How close the model's velocities and positions must come to the
/// engine's, relative to their largest value: the same arithmetic with the
/// node sums in another order, so round-off (measured after 20 steps: 1.2e-15
/// on 50^2 cells, 1.6e-14 on 500^2; 1.7e-15 after 100 steps on 50^2). The
/// check catches a different step: a held node's acceleration taken as
/// -q_I / (m_I dt) instead of 0 gives 0.13 after 2 steps, V_p = det F V_0
/// instead of m_p / rho_p 3e-11 after 20.
constexpr double kAgreement = 1e-12;

/// The nodal sums of the particle-to-node map (m_I, q_I, f_I).
struct NodeSums {
  double m = 0, qx = 0, qy = 0, fx = 0, fy = 0;
};
/// The nodal acceleration a_I = f_I / m_I and velocity v_I = q_I / m_I + dt a_I.
struct NodeRates {
  double ax = 0, ay = 0, vx = 0, vy = 0;
};
/// The four linear hats of a particle: its nodes and N, dN/dx, dN/dy.
struct Hats {
  int node[4];
  double N[4], dNx[4], dNy[4];
};

/// The grid and material constants of the sweep; the grid's nodes x = lo +
/// i h (i < NX), y = j h, node id j NX + i.
struct SweepConstants {
  double h, lo, lambda, mu, dt;
  int NX;
};

/// The linear hats at (px, py).
[[gnu::always_inline]] inline Hats linear_hats(double px, double py, const SweepConstants& c) {
  const double inv_h = 1.0 / c.h, u = (px - c.lo) * inv_h, w = py * inv_h;
  const int i = static_cast<int>(u), j = static_cast<int>(w), I = j * c.NX + i;
  const double a = u - i, b = w - j, Nx0 = 1 - a, Ny0 = 1 - b;
  return {{I, I + 1, I + c.NX, I + c.NX + 1},
          {Nx0 * Ny0, a * Ny0, Nx0 * b, a * b},
          {-inv_h * Ny0, inv_h * Ny0, -inv_h * b, inv_h * b},
          {-inv_h * Nx0, -inv_h * a, inv_h * Nx0, inv_h * a}};
}

/// Adds particle p's m_I, q_I = m_p v_p and f_I = -V_p sigma_p grad N + N m_p g to S.
[[gnu::always_inline]] inline void scatter_particle(const Hats& w, double mp, double Vp, double pvx,
                                                    double pvy, const double* s, NodeSums* __restrict S) {
  const double sxx = Vp * s[0], syy = Vp * s[1], sxy = Vp * s[2];
  const double qx = mp * pvx, qy = mp * pvy, fg = mp * -9.81;
  for (int k = 0; k < 4; ++k) {
    NodeSums& d = S[w.node[k]];
    d.m += w.N[k] * mp;
    d.qx += w.N[k] * qx, d.qy += w.N[k] * qy;
    d.fx -= sxx * w.dNx[k] + sxy * w.dNy[k];
    d.fy -= sxy * w.dNx[k] + syy * w.dNy[k];
    d.fy += w.N[k] * fg;
  }
}

/// The energy sums and the count of failed checks of one sweep.
struct SweepTotals {
  double kinetic = 0, strain = 0, speed2 = 0;
  long failed = 0;
};

/// The sweep over the particles, in batches of `Batch`: for each batch the
/// grid-to-particle update (v_p, x_p and the velocity gradient from the
/// nodes' a_I, v_I), then linear_elastic's update with the energy sums and
/// checks, then the next step's particle-to-node sums at the new x_p, each
/// stage a loop over the batch. Batch 1 is the fused loop (one particle
/// through all three); a larger batch gives the core short loops of
/// independent iterations. The arrays are restrict parameters and the sums
/// locals, so that the compiler keeps them in registers.
template <int Batch>
[[gnu::noinline]] SweepTotals
sweep_stages(int n, const SweepConstants c, double* __restrict x, double* __restrict y, double* __restrict vx,
             double* __restrict vy, const double* __restrict m, double* __restrict V, double* __restrict rho,
             double* __restrict eps, double* __restrict sigma, const NodeRates* __restrict R,
             NodeSums* __restrict S) {
  const double dt = c.dt, two_mu = 2 * c.mu;
  SweepTotals t;
  double G[4][Batch]; // dt L of the batch: xx, yy, (xy + yx) / 2, trace
  for (int p0 = 0; p0 < n; p0 += Batch) {
    const int nb = std::min(Batch, n - p0);
    for (int q = 0; q < nb; ++q) { // grid to particle
      const int p = p0 + q;
      const Hats w = linear_hats(x[p], y[p], c);
      double ax = 0, ay = 0, ux = 0, uy = 0, Lxx = 0, Lxy = 0, Lyx = 0, Lyy = 0;
      for (int k = 0; k < 4; ++k) {
        const NodeRates& o = R[w.node[k]];
        ax += w.N[k] * o.ax, ay += w.N[k] * o.ay, ux += w.N[k] * o.vx, uy += w.N[k] * o.vy;
        Lxx += o.vx * w.dNx[k], Lxy += o.vx * w.dNy[k], Lyx += o.vy * w.dNx[k], Lyy += o.vy * w.dNy[k];
      }
      vx[p] += dt * ax, vy[p] += dt * ay;
      x[p] += dt * ux, y[p] += dt * uy;
      G[0][q] = dt * Lxx, G[1][q] = dt * Lyy, G[2][q] = 0.5 * (dt * Lxy + dt * Lyx);
      G[3][q] = G[0][q] + G[1][q];
    }
    for (int q = 0; q < nb; ++q) { // eps += dt sym L, sigma += C : dt sym L, rho /= 1 + tr, V = m / rho
      const int p = p0 + q;
      const double gxx = G[0][q], gyy = G[1][q], dxy = G[2][q], tr = G[3][q];
      double* __restrict e = eps + 3 * static_cast<std::size_t>(p);
      double* __restrict s = sigma + 3 * static_cast<std::size_t>(p);
      e[0] += gxx, e[1] += gyy, e[2] += dxy;
      s[0] += c.lambda * tr + two_mu * gxx, s[1] += c.lambda * tr + two_mu * gyy, s[2] += two_mu * dxy;
      rho[p] /= 1.0 + tr;
      V[p] = m[p] / rho[p];
      // kinetic and stored energy, the fastest particle, the finiteness check
      const double v2 = vx[p] * vx[p] + vy[p] * vy[p];
      t.kinetic += 0.5 * m[p] * v2;
      t.strain += 0.5 * V[p] * (s[0] * e[0] + s[1] * e[1] + 2 * s[2] * e[2]);
      t.speed2 = std::max(t.speed2, v2);
      const double z = (x[p] - x[p]) + (y[p] - y[p]) + (s[0] - s[0]) + (s[1] - s[1]) + (s[2] - s[2]);
      t.failed += !(z == 0.0);
    }
    for (int q = 0; q < nb; ++q) { // the next step's particle-to-node sums
      const int p = p0 + q;
      scatter_particle(linear_hats(x[p], y[p], c), m[p], V[p], vx[p], vy[p],
                       sigma + 3 * static_cast<std::size_t>(p), S);
    }
  }
  return t;
}

#ifdef OTMPM_WIDE_LANES
/// Four doubles, one particle per lane: the library's four-lane type (AVX registers in sweep_lanes).
using Lanes = plasticity::point::Lanes4;
/// Four ints, one particle per lane.
using LaneInts = int __attribute__((vector_size(16)));
/// A comparison's lanes: all bits set where it holds.
using LaneFlags = plasticity::point::Mask4;

[[gnu::target("avx2"), gnu::always_inline]] inline Lanes load(const double* p) {
  Lanes v;
  std::memcpy(&v, p, sizeof v);
  return v;
}
[[gnu::target("avx2"), gnu::always_inline]] inline void store(double* p, Lanes v) {
  std::memcpy(p, &v, sizeof v);
}

/// The linear hats of four particles, one per lane: the lowest node of each
/// cell and N, dN/dx, dN/dy of its four corners, linear_hats' operations
/// lane by lane (the same bits).
struct LaneHats {
  LaneInts node;
  Lanes N[4], dNx[4], dNy[4];
};

[[gnu::target("avx2"), gnu::always_inline]] inline LaneHats lane_hats(Lanes px, Lanes py,
                                                                      const SweepConstants& c) {
  const double inv_h = 1.0 / c.h;
  const Lanes u = (px - c.lo) * inv_h, w = py * inv_h;
  const LaneInts i = __builtin_convertvector(u, LaneInts), j = __builtin_convertvector(w, LaneInts);
  const Lanes a = u - __builtin_convertvector(i, Lanes), b = w - __builtin_convertvector(j, Lanes);
  const Lanes Nx0 = 1.0 - a, Ny0 = 1.0 - b;
  LaneHats h;
  h.node = j * c.NX + i;
  h.N[0] = Nx0 * Ny0, h.N[1] = a * Ny0, h.N[2] = Nx0 * b, h.N[3] = a * b;
  h.dNx[0] = -inv_h * Ny0, h.dNx[1] = inv_h * Ny0, h.dNx[2] = -inv_h * b, h.dNx[3] = inv_h * b;
  h.dNy[0] = -inv_h * Nx0, h.dNy[1] = -inv_h * a, h.dNy[2] = inv_h * Nx0, h.dNy[3] = inv_h * a;
  return h;
}

/// Four rows of four doubles turned into four columns: r[i][l] becomes r[l][i].
[[gnu::target("avx2"), gnu::always_inline]] inline void transpose4(Lanes r[4]) {
  const Lanes t0 = __builtin_shufflevector(r[0], r[1], 0, 4, 2, 6),
              t1 = __builtin_shufflevector(r[0], r[1], 1, 5, 3, 7),
              t2 = __builtin_shufflevector(r[2], r[3], 0, 4, 2, 6),
              t3 = __builtin_shufflevector(r[2], r[3], 1, 5, 3, 7);
  r[0] = __builtin_shufflevector(t0, t2, 0, 1, 4, 5), r[1] = __builtin_shufflevector(t1, t3, 0, 1, 4, 5);
  r[2] = __builtin_shufflevector(t0, t2, 2, 3, 6, 7), r[3] = __builtin_shufflevector(t1, t3, 2, 3, 6, 7);
}

/// sweep_stages<32> with four particles per instruction (AVX2 across
/// particles, no fused multiply-adds), the same bits: the hats, the
/// grid-to-particle sums (each lane's node rates loaded as one row and
/// turned into columns), the stress update and the sums on four particles at
/// once; the scatter turns each corner's lanes of (N m, N q_x, N q_y, -V
/// sigma grad N . e_x) into rows and adds each to its node with one
/// instruction, particle by particle, so each node receives the scalar
/// sweep's terms in the scalar sweep's order. The energy sums are taken per
/// lane and added at the end (another order; nothing is checked against
/// them). n must be a multiple of 4.
[[gnu::target("avx2"), gnu::noinline]] SweepTotals
sweep_lanes(int n, const SweepConstants c, double* __restrict x, double* __restrict y, double* __restrict vx,
            double* __restrict vy, const double* __restrict m, double* __restrict V, double* __restrict rho,
            double* __restrict eps, double* __restrict sigma, const NodeRates* __restrict R,
            NodeSums* __restrict S) {
  constexpr int Batch = 32;
  const double dt = c.dt, two_mu = 2 * c.mu;
  const int corner[4] = {0, 1, c.NX, c.NX + 1};
  Lanes kinetic{}, strain{}, speed2{};
  LaneFlags failed{};
  Lanes G[4][Batch / 4]; // dt L of the batch: xx, yy, (xy + yx) / 2, trace
  for (int p0 = 0; p0 < n; p0 += Batch) {
    const int nb = std::min(Batch, n - p0);
    for (int q = 0; q < nb; q += 4) { // grid to particle
      const int p = p0 + q;
      const Lanes px = load(x + p), py = load(y + p);
      const LaneHats w = lane_hats(px, py, c);
      Lanes ax{}, ay{}, ux{}, uy{}, Lxx{}, Lxy{}, Lyx{}, Lyy{};
      for (int k = 0; k < 4; ++k) {
        Lanes o[4]; // lane l's node rates (a_x, a_y, v_x, v_y), then the lanes' a_x, a_y, v_x, v_y
        for (int l = 0; l < 4; ++l) o[l] = load(&R[w.node[l] + corner[k]].ax);
        transpose4(o);
        ax += w.N[k] * o[0], ay += w.N[k] * o[1], ux += w.N[k] * o[2], uy += w.N[k] * o[3];
        Lxx += o[2] * w.dNx[k], Lxy += o[2] * w.dNy[k], Lyx += o[3] * w.dNx[k], Lyy += o[3] * w.dNy[k];
      }
      store(vx + p, load(vx + p) + dt * ax), store(vy + p, load(vy + p) + dt * ay);
      store(x + p, px + dt * ux), store(y + p, py + dt * uy);
      G[0][q / 4] = dt * Lxx, G[1][q / 4] = dt * Lyy, G[2][q / 4] = 0.5 * (dt * Lxy + dt * Lyx);
      G[3][q / 4] = G[0][q / 4] + G[1][q / 4];
    }
    for (int q = 0; q < nb; q += 4) { // the stress update, the sums and checks, the particle-to-node sums
      const int p = p0 + q;
      const Lanes gxx = G[0][q / 4], gyy = G[1][q / 4], dxy = G[2][q / 4], tr = G[3][q / 4];
      double* e = eps + 3 * static_cast<std::size_t>(p);
      double* s = sigma + 3 * static_cast<std::size_t>(p);
      Lanes E[3], T[3]; // eps and sigma of the four particles, component by component
      for (int i = 0; i < 3; ++i) E[i] = Lanes{e[i], e[3 + i], e[6 + i], e[9 + i]};
      for (int i = 0; i < 3; ++i) T[i] = Lanes{s[i], s[3 + i], s[6 + i], s[9 + i]};
      E[0] += gxx, E[1] += gyy, E[2] += dxy;
      T[0] += c.lambda * tr + two_mu * gxx, T[1] += c.lambda * tr + two_mu * gyy, T[2] += two_mu * dxy;
      for (int l = 0; l < 4; ++l)
        for (int i = 0; i < 3; ++i) e[3 * l + i] = E[i][l], s[3 * l + i] = T[i][l];
      const Lanes r = load(rho + p) / (1.0 + tr), mp = load(m + p), Vp = mp / r;
      store(rho + p, r), store(V + p, Vp);
      const Lanes px = load(x + p), py = load(y + p), pvx = load(vx + p), pvy = load(vy + p);
      const Lanes v2 = pvx * pvx + pvy * pvy;
      kinetic += 0.5 * mp * v2;
      strain += 0.5 * Vp * (T[0] * E[0] + T[1] * E[1] + 2 * T[2] * E[2]);
      speed2 = speed2 > v2 ? speed2 : v2;
      const Lanes z = (px - px) + (py - py) + (T[0] - T[0]) + (T[1] - T[1]) + (T[2] - T[2]);
      failed -= z != 0.0;
      // the next step's particle-to-node sums
      const LaneHats w = lane_hats(px, py, c);
      const Lanes sxx = Vp * T[0], syy = Vp * T[1], sxy = Vp * T[2], qx = mp * pvx, qy = mp * pvy,
                  fg = mp * -9.81;
      Lanes rows[4][4], fy[4][2]; // per corner: the rows of the lanes; -(V sigma grad N) . e_y and N m g
      for (int k = 0; k < 4; ++k) {
        rows[k][0] = w.N[k] * mp, rows[k][1] = w.N[k] * qx, rows[k][2] = w.N[k] * qy;
        rows[k][3] = -(sxx * w.dNx[k] + sxy * w.dNy[k]); // f_x - t is f_x + (-t), bit for bit
        transpose4(rows[k]);
        fy[k][0] = sxy * w.dNx[k] + syy * w.dNy[k], fy[k][1] = w.N[k] * fg;
      }
      for (int l = 0; l < 4; ++l)
        for (int k = 0; k < 4; ++k) {
          NodeSums& d = S[w.node[l] + corner[k]];
          store(&d.m, load(&d.m) + rows[k][l]); // m, q_x, q_y, f_x
          d.fy -= fy[k][0][l];
          d.fy += fy[k][1][l];
        }
    }
  }
  SweepTotals t;
  for (int l = 0; l < 4; ++l) {
    t.kinetic += kinetic[l], t.strain += strain[l];
    t.speed2 = std::max(t.speed2, speed2[l]);
    t.failed += static_cast<long>(failed[l]);
  }
  return t;
}
#endif

/// The 2D block's linear `fe` step as one sweep over the particles (see the file's head).
class OnePassBlock {
public:
  /// `batch`: the sweep's batch (1 or 32; sweep_stages); `lanes` 4: sweep_lanes.
  OnePassBlock(const Engine<2>& e, int cells, int batch, int lanes)
      : c_{1.0 / cells, -2.0 / cells, 0.0, 0.0, 0.0, cells + 5}, NY_(cells + 3), batch_(batch),
        lanes_(lanes) {
    const Particles<2>& P = e.particles();
    const int n = static_cast<int>(P.size());
    for (int p = 0; p < n; ++p) {
      x_.push_back(P.x[p].x()), y_.push_back(P.x[p].y()), vx_.push_back(P.v[p].x()),
          vy_.push_back(P.v[p].y());
      m_.push_back(P.m[p]), V_.push_back(P.V[p]), rho_.push_back(P.rho[p]);
      eps_.insert(eps_.end(), {0.0, 0.0, 0.0});
      sigma_.insert(sigma_.end(), {0.0, 0.0, 0.0});
    }
    const double E = 1e7, nu = 0.3; // the block's material (bench_scenes.hpp)
    c_.lambda = E * nu / ((1 + nu) * (1 - 2 * nu)), c_.mu = E / (2 * (1 + nu));
    sums_.assign(static_cast<std::size_t>(c_.NX) * NY_, NodeSums{});
    next_ = sums_;
    rates_.assign(sums_.size(), NodeRates{});
    for (int p = 0; p < n; ++p)
      scatter_particle(linear_hats(x_[p], y_[p], c_), m_[p], V_[p], vx_[p], vy_[p], &sigma_[3 * p],
                       sums_.data());
  }
  /// One step of size dt: the nodal update, then the sweep.
  void step(double dt) {
    nodal_update(dt);
    c_.dt = dt;
    auto sweep = batch_ == 32 ? sweep_stages<32> : sweep_stages<1>;
#ifdef OTMPM_WIDE_LANES
    if (lanes_ == 4) sweep = sweep_lanes;
#endif
    totals_ = sweep(size(), c_, x_.data(), y_.data(), vx_.data(), vy_.data(), m_.data(), V_.data(),
                    rho_.data(), eps_.data(), sigma_.data(), rates_.data(), next_.data());
    std::swap(sums_, next_);
  }
  int size() const { return static_cast<int>(x_.size()); }
  double vx(int p) const { return vx_[p]; }
  double vy(int p) const { return vy_[p]; }
  double x(int p) const { return x_[p]; }
  double y(int p) const { return y_[p]; }
  long failed() const { return totals_.failed; }

private:
  /// a_I, v_I of every node with mass; the base's row (y = 0) held: v_I = 0 and, as the engine's Dirichlet
  /// sets give it (the fixed components of f_I zeroed), a_I = 0.
  void nodal_update(double dt) {
    for (int r = 0; r < NY_; ++r)
      for (int i = 0; i < c_.NX; ++i) {
        const std::size_t I = static_cast<std::size_t>(r) * c_.NX + i;
        const NodeSums& d = sums_[I];
        NodeRates& o = rates_[I];
        if (d.m > 0 && r > 0) {
          o.ax = d.fx / d.m, o.ay = d.fy / d.m;
          o.vx = d.qx / d.m + dt * o.ax, o.vy = d.qy / d.m + dt * o.ay;
        } else if (d.m > 0)
          o = {0.0, 0.0, 0.0, 0.0};
        else
          o = NodeRates{};
        next_[I] = NodeSums{};
      }
  }

  SweepConstants c_;
  int NY_, batch_, lanes_;
  std::vector<double> x_, y_, vx_, vy_, m_, V_, rho_, eps_, sigma_;
  std::vector<NodeSums> sums_, next_;
  std::vector<NodeRates> rates_;
  SweepTotals totals_;
};

/// Steps the engine and the model `steps` times with the engine's dt and
/// returns the largest difference of velocity and position, each relative
/// to the largest value of its field.
double agreement(const Scene& scene, int cells, int steps, int batch, int lanes) {
  Engine<2> e = assemble<2>(scene);
  OnePassBlock b(e, cells, batch, lanes);
  for (int s = 0; s < steps; ++s) {
    e.step();
    b.step(e.last_dt());
  }
  const Particles<2>& P = e.particles();
  double dv = 0, vmax = 0, dx = 0, xmax = 0;
  for (int p = 0; p < b.size(); ++p) {
    dv = std::max({dv, std::abs(b.vx(p) - P.v[p].x()), std::abs(b.vy(p) - P.v[p].y())});
    dx = std::max({dx, std::abs(b.x(p) - P.x[p].x()), std::abs(b.y(p) - P.x[p].y())});
    vmax = std::max(vmax, P.v[p].norm()), xmax = std::max(xmax, P.x[p].norm());
  }
  return std::max(dv / vmax, dx / xmax);
}

/// The particles of the scalar sweep (sweep_stages<32>) and of sweep_lanes
/// after `steps` steps of the engine's dt that differ in any bit of v_p or x_p.
int lanes_differ(const Scene& scene, int cells, int steps) {
  Engine<2> e = assemble<2>(scene);
  OnePassBlock scalar(e, cells, 32, 1), lanes(e, cells, 32, 4);
  for (int s = 0; s < steps; ++s) {
    e.step();
    scalar.step(e.last_dt()), lanes.step(e.last_dt());
  }
  int differ = 0;
  for (int p = 0; p < scalar.size(); ++p)
    differ += scalar.vx(p) != lanes.vx(p) || scalar.vy(p) != lanes.vy(p) || scalar.x(p) != lanes.x(p) ||
              scalar.y(p) != lanes.y(p);
  return differ;
}

/// Particle-steps per second of `steps` model steps (after one untimed step).
double time_model(const Scene& scene, int cells, int steps, int batch, int lanes) {
  Engine<2> e = assemble<2>(scene);
  OnePassBlock b(e, cells, batch, lanes);
  const double dt = e.stable_dt();
  b.step(dt);
  const auto t0 = std::chrono::steady_clock::now();
  for (int s = 0; s < steps; ++s) b.step(dt);
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (b.failed() != 0) std::fprintf(stderr, "bench_one_pass: %ld particles not finite\n", b.failed());
  return double(b.size()) * steps / wall;
}

} // namespace

int main(int argc, char** argv) {
  otmpm::default_openmp_wait(argv);
  int cells = 500, steps = 50, repeat = 5, check = 20, with_engine = 1, batch = 1, lanes = 1;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string a = argv[i], v = argv[i + 1];
    if (a == "--cells")
      cells = std::stoi(v);
    else if (a == "--steps")
      steps = std::stoi(v);
    else if (a == "--repeat")
      repeat = std::stoi(v);
    else if (a == "--check")
      check = std::stoi(v);
    else if (a == "--engine")
      with_engine = std::stoi(v);
    else if (a == "--batch")
      batch = std::stoi(v);
    else if (a == "--lanes")
      lanes = std::stoi(v);
  }
  if (batch != 1 && batch != 32) {
    std::fprintf(stderr, "bench_one_pass: --batch takes 1 or 32\n");
    return 2;
  }
  if (lanes != 1 && !(lanes == 4 && batch == 32 && plasticity::point::wide_lanes())) {
    std::fprintf(stderr, "bench_one_pass: --lanes takes 1, or 4 with --batch 32 on a core with AVX2\n");
    return 2;
  }
  const Scene scene = parse_scene(block_scene(2, cells, "linear", "fe", "mpm", 3.0), "bench_one_pass.toml");
  const double differ = agreement(scene, cells, check, batch, lanes);
  std::printf(
      "one-pass model against the engine after %d steps: velocities and positions within %.1e of their "
      "scale (bound %.0e)\n",
      check, differ, kAgreement);
  if (!(differ <= kAgreement)) return 1;
  if (lanes == 4) {
    const int bits = lanes_differ(scene, cells, check);
    std::printf(
        "four lanes against the scalar sweep (batch 32) after %d steps: %d particles differ in any bit\n",
        check, bits);
    if (bits != 0) return 1;
  }
  std::vector<double> model, engine;
  for (int r = 0; r < repeat; ++r) {
    model.push_back(time_model(scene, cells, steps, batch, lanes));
    if (!with_engine) continue;
    const Timing t = time_run<2>(scene, steps, 1);
    engine.push_back(double(t.particles) / t.per_step);
  }
  if (!with_engine) {
    std::printf(
        "block %d^2 cells, one-pass model (batch %d, lanes %d), median of %d rounds: %.3e particle-steps/s\n",
        cells, batch, lanes, repeat, median(model));
    return 0;
  }
  std::printf("block %d^2 cells, linear fe, one thread, median of %d rounds: one-pass model (batch %d, lanes "
              "%d) %.3e, "
              "engine %.3e particle-steps/s (model / engine %.2f)\n",
              cells, repeat, batch, lanes, median(model), median(engine), median(model) / median(engine));
  return 0;
}
