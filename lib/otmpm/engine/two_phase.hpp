#pragma once
/// \file two_phase.hpp
/// Saturated bodies: the liquid phase of the single-point two-phase
/// formulation with solid and liquid velocities on the nodes (docs/theory.md
/// sect. 15). Each particle of a saturated material carries, besides the
/// skeleton's state, the pore pressure p_p (compression positive) and the
/// liquid velocity w_p (Particles::state "pore_pressure" and
/// "liquid_velocity": checkpointed and written like any state).
/// The engine's particle mass m_p is the solid's; the liquid's is
/// n_p rho_w V_p. A step of an integrator that steps saturated bodies
/// (IntegratorKind::two_phase) calls, after the engine's own stages:
///   to_nodes        the liquid's nodal mass, momentum, Darcy drag and forces,
///                   and the nodal solve of both phases with the drag taken
///                   implicitly (eq. 15.5); the solid's force f_I becomes
///                   m_s a_s, so that the engine's nodal update is unchanged;
///   nodal_velocity  the liquid's nodal velocity (held components: the solid's);
///   to_particles    w_p += dt sum N a_w, p_p from the phases' volumetric
///                   rates (eq. 15.3); musl: remap (w_p, the re-projection of
///                   w, the rigid plates) before the stress update, then
///                   update_pressure.
/// fe and musl have the engine sum the liquid's to_nodes sums in its own
/// scatter (ToNodes::liquid), fe its particle update in its own particle
/// pass (ToParticles::liquid): one traversal of the basis table each way.
/// The Darcy dissipation is booked in the engine's energy balance
/// (EnergyBalance::darcy); the stages' time in the engine's phase timers.
#include "otmpm/basis/basis.hpp"
#include "otmpm/engine/constraints.hpp"
#include "otmpm/materials/pore_fluid.hpp"
#include "otmpm/particles/particles.hpp"
#include "otmpm/time_function.hpp"

#include <array>
#include <memory>
#include <optional>
#include <span>
#include <unordered_map>
#include <utility>
#include <vector>

namespace otmpm {

template <int D> class Engine;
template <int D> struct NodalFields;
template <int D> struct LiquidSums;
template <int D> struct MixtureSums;
template <int D, class Sums> class BlockedScatter;

/// A rigid, frictionless, impermeable plate: the listed nodes move together
/// along `axis` (both phases), massless, pressed by `force` g(t); the nodal
/// forces along the axis are shared so that they keep one velocity. The other
/// components stay free.
struct Plate {
  std::vector<int> node;
  int axis = 0;
  double force = 0.0;
  TimeFunction time;
};

/// A drained surface in contact with free water: the nodes of a
/// `[[boundary]]` with `pore_pressure` or `water_level`. The free water's
/// pressure at a node x_I is (docs/theory.md eq. 15.11)
///   pbar(x, t) = pressure + density max(0, |b| level(t) + b . x),
/// level(t) = level + rise g(t) the water level's height along -b (b the
/// uniform body force, g the time function `time`),
/// and it pushes on the surface: -pbar G_I on the mixture, -pbar G_n,I on
/// the liquid (G_I = sum_p V_p grad N_Ip, G_n,I with n_p V_p: the surface
/// integrals of N_I n_s over the body's surface and its pores).
struct Drain {
  std::vector<int> node;
  double pressure = 0.0;
  std::optional<double> level; ///< none: no hydrostatic part
  double density = 0.0;        ///< of the free water (the pore fluid's)
  double rise = 0.0;           ///< of the level, times time(t)
  TimeFunction time;
};

/// What the liquid phase of a run is built from.
template <int D> struct TwoPhaseParts {
  /// The pore fluid of each material (indexed as Particles::material); nullopt: dry.
  std::vector<std::optional<PoreFluid>> fluid;
  /// The components where the liquid is held with the solid (an impermeable
  /// support): the fixed components of the Dirichlet sets that are not
  /// drained. Every entry must also be a fixed component of the engine's
  /// Dirichlet sets.
  Dirichlet<D> held;
  std::vector<Plate> plates;
  /// The drained surfaces. Every other surface of a saturated body is
  /// impermeable: at a node of the body's surface (a node with an empty
  /// lattice cell beside it) the liquid's normal velocity is the solid's,
  /// (w - v) . n_I = 0 with n_I along G_I (eq. 15.10).
  std::vector<Drain> drains;
};

/// The liquid's contributions to the after-step sums (Engine::sum_particles):
/// kinetic energy sum 1/2 m_w |w|^2, stored energy sum V n p^2 / (2 K_w),
/// the step's increment of W_a (eq. 15.13; summed by the pressure update
/// only), momentum sum m_w w, the largest squared fast-wave speed (eq. 15.7)
/// and the first particle whose pore pressure or liquid velocity is not
/// finite (-1: none).
template <int D> struct LiquidTotals {
  double kinetic = 0.0, stored = 0.0, averaged = 0.0, wave_speed2 = 0.0;
  Vec<D> momentum = Vec<D>::Zero();
  int bad = -1;
  LiquidTotals& operator+=(const LiquidTotals& o);
};

/// The liquid's sums over the basis table row of particle p in a
/// node-to-particle pass (eq. 15.3): sum_I N_Ip a_w,I (the liquid's rate)
/// and the divergences sum_I v_I . grad N_Ip and sum_I w_I . grad N_Ip of
/// the solid's and the liquid's nodal velocities.
template <int D> struct LiquidRow {
  Vec<D> a = Vec<D>::Zero();
  double div_s = 0.0, div_w = 0.0;
};

/// The LiquidRow of each particle of a batch of at most `size` particles:
/// the engine's pass with ToParticles::liquid sums them beside its own
/// (add: entry by entry, in row order), TwoPhase::finish_rows takes them.
template <int D> struct LiquidRows {
  static constexpr int size = 64;
  const Vec<D>* v = nullptr;  ///< the solid's nodal velocity v_I
  const Vec<D>* vw = nullptr; ///< the liquid's w_I
  const Vec<D>* aw = nullptr; ///< the liquid's a_w,I
  LiquidRow<D> row[size];
  /// Adds the entry of node I with N_Ip = N and grad N_Ip = dN to r: the
  /// rate (Rate) and the divergences (Pressure).
  template <bool Rate = true, bool Pressure = true> void add(LiquidRow<D>& r, int I, double N, const Vec<D>& dN) const {
    if constexpr (Rate) r.a += N * aw[I];
    if constexpr (Pressure) r.div_s += v[I].dot(dN), r.div_w += vw[I].dot(dN);
  }
};

/// The liquid phase of the saturated particles of an engine.
template <int D> class TwoPhase {
public:
  /// Adds the state arrays to P (a fresh array starts at p = 0 and w = v_p).
  /// `dirichlet` are the engine's Dirichlet sets on `nodes` nodes.
  /// std::invalid_argument when the parts do not fit.
  TwoPhase(TwoPhaseParts<D> parts, Particles<D>& P, const Dirichlet<D>& dirichlet, int nodes);
  ~TwoPhase();

  /// After the engine's to_nodes (mass, momentum, forces at t): the liquid's
  /// sums and the coupled nodal solve; f_I becomes m_s a_s, the Darcy
  /// dissipation of the step is added to darcy() and the plates' work to
  /// take_boundary_work().
  void to_nodes(Engine<D>& e, double t, double dt);
  /// The engine's particle-to-node pass at the start of a step
  /// (Engine::to_nodes with ToNodes::liquid) with the liquid's sums of
  /// to_nodes beside it, in one traversal of the basis table
  /// (two_phase_scatter.hpp): the engine's prep, add, merge and clear on
  /// NodeSums (BlockedScatter::run), the liquid's on their own buffers. The
  /// next to_nodes then takes the sums as summed. The same bits as two passes.
  template <class Update, class Prep, class Add, class Merge, class Clear>
  void scatter_with(const Engine<D>& e, Update&& update, Prep&& prep, Add&& add, Merge&& merge, Clear&& clear);
  /// The work the plates' forces and the free water's push on drained
  /// surfaces did in the steps since the last call (the engine adds it to
  /// W_ext): (F(t_n) + F(t_n+1)) / 2 . dt V for each step and plate,
  /// F . dt (u_n + u_n+1) / 2 for each drained node and phase; less dt
  /// held_power at t_n, which the engine's body-force work counts but no
  /// held component does.
  double take_boundary_work() { return std::exchange(boundary_work_, 0.0); }
  /// A distributed run: the free water's work on this rank's own drained
  /// nodes since the last call (the rest of take_boundary_work() is the same
  /// on every rank); the engine sums it over the ranks. Zero in a serial run.
  double take_rank_work() { return std::exchange(rank_work_, 0.0); }
  /// The energy the Darcy drag dissipated since t = 0 (W_d, eq. 15.6; EnergyBalance::darcy).
  double darcy() const { return darcy_; }
  /// Sets W_d (a restart).
  void set_darcy(double w) { darcy_ = w; }
  /// The work the pore pressure did since t = 0 on the pressure increments
  /// that the cell average (eq. 15.3a) takes from each particle
  /// (W_a, eq. 15.13; EnergyBalance::pressure_average): energy the liquid's
  /// stored energy does not keep (negative: energy it gained).
  double pressure_average() const { return averaged_; }
  /// Sets W_a (a restart).
  void set_pressure_average(double w) { averaged_ = w; }
  /// A distributed run: adds the step's W_a summed over the ranks (the
  /// LiquidTotals::averaged of each rank's totals()).
  void add_pressure_average(double w) { averaged_ += w; }
  /// The particles were given other positions between steps (a restart):
  /// the lattice cells the last pressure update found no longer hold.
  void forget_cells() { cells_ready_ = false; }
  /// After the engine's constrained nodal velocity v_I: the liquid's w_I.
  void nodal_velocity(Engine<D>& e, double dt);
  /// After the particles moved and their stresses were updated: w_p and p_p
  /// (after an engine pass that took ToParticles::liquid: the cell average of
  /// the pressure increments that pass found).
  void to_particles(Engine<D>& e, double dt);
  /// Before an engine pass with ToParticles::liquid (fe): the step's dt and
  /// the arrays the pass fills.
  void begin_rows(const Engine<D>& e, double dt);
  /// The nodal fields a LiquidRows reads: v_I, w_I and a_w,I of the step.
  void bind(const Engine<D>& e, LiquidRows<D>& rows) const {
    rows.v = e.nodal().v.data(), rows.vw = vw_.data(), rows.aw = aw_.data();
  }
  /// In that pass, after particles [p0, p1) (a batch, at most
  /// LiquidRows::size) moved and their stresses were updated, from their
  /// row sums: w_p += dt sum N a_w, the pore pressure increments (eq. 15.3)
  /// and the lattice cells that to_particles then averages over.
  void finish_rows(Engine<D>& e, int p0, int p1, const LiquidRows<D>& rows);
  /// As finish_rows on particles [p0, p1) with their own traversal of the
  /// table (an engine pass without the gradient: F-bar).
  void update_rows(Engine<D>& e, int p0, int p1);
  /// musl, after the re-projection of the solid's momenta and before the
  /// stress update: w_p, the re-projection of the liquid's momenta, and the
  /// rigid plates on both phases' re-projected velocities.
  void remap(Engine<D>& e, double dt);
  /// musl, after the stress update: p_p from the re-projected velocities.
  void update_pressure(Engine<D>& e, double dt);
  /// The liquid's after-step sums (LiquidTotals), in fixed blocks of
  /// particles: those the step's last pass took (once), else summed anew.
  LiquidTotals<D> totals(const Engine<D>& e);
  /// A distributed run: the inputs of the fast-wave bound (eq. 15.7) of
  /// add_totals' groups - the particles of one material in one reduction
  /// block of global ids (a serial run's runs) - as maxima to reduce over
  /// the ranks: per group the skeleton's largest c^2, minus the smallest
  /// porosity, minus the smallest density. Collective at its first call.
  std::vector<double> wave_maxima(const Engine<D>& e);
  /// The largest squared fast-wave speed of the groups of wave_maxima
  /// reduced over the ranks: the serial run's LiquidTotals::wave_speed2.
  double wave_speed2(std::span<const double> maxima) const;
  /// The liquid's momentum sum_p m_w w_p.
  Vec<D> momentum(const Particles<D>& P) const;
  /// The pore fluid of material `m`, or null when it is dry.
  const PoreFluid* fluid(int m) const { return fluids_[static_cast<std::size_t>(m)]; }
  /// The porosity of particle p: n = 1 - (1 - n_0) V0_p / V_p (incompressible grains).
  static double porosity(const PoreFluid& f, double V0, double V) { return 1.0 - (1.0 - f.porosity) * V0 / V; }
  /// Per node: the unit normal of an impermeable surface node over its free
  /// components, or zero (an interior, drained, held or dry node).
  const AlignedVector<Vec<D>>& impermeable_normal() const { return normal_; }
  /// The liquid's nodal fields of the step: mass, drag coefficient, velocity, acceleration.
  const std::vector<double>& liquid_mass() const { return mw_; }
  const AlignedVector<Vec<D>>& liquid_velocity() const { return vw_; }
  const AlignedVector<Vec<D>>& liquid_acceleration() const { return aw_; }

private:
  /// The liquid's particle-to-node sums (momentum only: musl's re-projection);
  /// update(p0, p1) runs on each block of particles before it is summed.
  template <bool MomentumOnly, class Update> void scatter(const Engine<D>& e, Update&& update);
  /// Calls sum(prep, add, merge, clear) with the liquid's closures for
  /// BlockedScatter::run on LiquidSums (two_phase_scatter.hpp).
  template <bool MomentumOnly, class Sum> void with_sums(const Engine<D>& e, Sum&& sum);
  /// The part of the body force's power P = b . (sum_p m_p v_p + sum_p m_w,p w_p)
  /// (the engine's W_ext, sect. 11) that falls on the momenta the particles bring to
  /// the fixed components, which move at their prescribed velocity instead
  /// (eq. 15.14): sum_{I,k fixed} b_k (q_Ik - m_I vbar_Ik), with the liquid's
  /// (q_w, m_w) where it is held.
  double held_power(const Engine<D>& e, const Vec<D>& b) const;
  /// The coupled nodal solve (eq. 15.5); returns the step's Darcy dissipation (eq. 15.6).
  double solve(Engine<D>& e, double t, double dt);
  /// The solve of node I's free components with (w - v) . normal = 0 at
  /// the end of the step (eq. 15.10); returns its dissipation.
  double solve_impermeable(NodalFields<D>& n, std::size_t I, const Vec<D>& Fm, const Vec<D>& Fw,
                           const Vec<D>& normal, double dt);
  /// Per node the lattice cells beside it that hold a saturated particle
  /// (around_; a distributed run: this rank's particles, exchange() sums them).
  void count_occupied(const Engine<D>& e);
  /// The impermeable normals of the step (normal_): the nodes beside a
  /// lattice cell without saturated particles (count_occupied).
  void find_surface(const Engine<D>& e);
  /// A distributed run: completes the liquid's nodal sums over the ranks
  /// (q_w alone: `momentum_only`), as the engine's own; nothing in a serial run.
  void exchange(Engine<D>& e, bool momentum_only);
  /// Per plate its mass M, momentum and (`forces`) force F(t) + sum F_m along
  /// its axis over its active nodes (a distributed run: this rank's own
  /// nodes, without F(t)), summed over the ranks.
  std::vector<double> plate_sums(const Engine<D>& e, double t, bool forces) const;
  /// The plates: one velocity per plate along its axis for both phases, from `sums` (plate_sums).
  void tie(Engine<D>& e, double t, double dt, const std::vector<double>& sums);
  /// A distributed run: each saturated particle's mean pressure increment
  /// of its lattice cell (eq. 15.3a) in means_. A cell's particles may be on
  /// two ranks after the step moved them (they migrate before the next):
  /// each rank adds its particles' V dp and V at every corner node of their
  /// cell in its window (one slot per corner), the ranks complete those
  /// sums, and a particle takes its cell's sums from the corner with the
  /// largest V (the corner that every rank with particles there holds).
  void distributed_means(Engine<D>& e);
  /// w_p += dt sum N a_w (rate) and the pore pressure update (pressure) of all particles.
  void update_particles(Engine<D>& e, double dt, bool rate, bool pressure);
  /// update_particles on particles [p0, p1), rows of W entries (0: any length).
  template <bool Rate, bool Pressure, int W> void update_range(Engine<D>& e, double dt, int p0, int p1);
  /// The end of the update of particles [p0, p1) from their row sums (finish_rows).
  template <bool Rate, bool Pressure>
  void finish(Engine<D>& e, double dt, int p0, int p1, const LiquidRows<D>& rows);
  /// p_p += the volume-weighted mean of the pressure increments of the
  /// particles in its lattice cell (eq. 15.3a).
  void average_pressure(Engine<D>& e);
  /// Adds particles [b0, b1) to the after-step sums (runs of one material).
  void add_totals(const Engine<D>& e, int b0, int b1, LiquidTotals<D>& acc) const;
  /// The patch number of lattice cell `cell` (of `cells`) in this step's sums.
  int patch_of(long long cell, long long cells);

  TwoPhaseParts<D> parts_;
  /// Per node component (I D + k): fixed by the solid's Dirichlet sets, the
  /// liquid held with it, tied by a rigid set; the solid's prescribed velocity.
  std::vector<char> fixed_, held_, rigid_;
  std::vector<double> value_;
  std::vector<std::size_t> fixed_list_; ///< the fixed components (I D + k), ascending
  std::vector<char> wet_;         ///< per node: active with a liquid mass above the mass tolerance
  std::vector<int> drain_;        ///< per node: its Drain in parts_.drains, or -1
  std::vector<char> occupied_;    ///< per lattice cell (its lower corner's node): holds a saturated particle
  /// G_I and G_n,I (Drain), the impermeable normals (impermeable_normal).
  AlignedVector<Vec<D>> g_, gn_, normal_;
  std::vector<double> mw_, drag_; ///< m_w,I and Q_I
  /// q_w, f_w, f_p, the mixture's force F_m, w_I and a_w of the step.
  AlignedVector<Vec<D>> qw_, fw_, fp_, fm_, vw_, aw_;
  std::unique_ptr<BlockedScatter<D, LiquidSums<D>>> scatter_;
  std::unique_ptr<BlockedScatter<D, MixtureSums<D>>> mixture_; ///< scatter_with's
  bool summed_ = false; ///< scatter_with summed the liquid's sums of this step's to_nodes
  double rows_dt_ = 0.0; ///< begin_rows' dt
  bool gathered_ = false; ///< begin_rows: the engine's pass updates the particles
  /// The pressure update: each particle's increment and lattice cell, its
  /// patch, and per patch sum V dp (then the mean increment) and sum V.
  std::vector<double> dp_;
  std::vector<long long> cell_;
  std::vector<int> patch_;
  std::vector<std::array<double, 2>> sums_;
  std::vector<int> slot_;         ///< per lattice cell its patch in this step, or -1 (a lattice not too large)
  std::vector<long long> used_;   ///< the cells slot_ numbered in this step
  std::unordered_map<long long, int> number_; ///< the patches of a large lattice
  std::vector<const PoreFluid*> fluids_; ///< per material its pore fluid, or null
  int width_ = 0;                 ///< linear_row_width of this step's table
  long long blocks_ = -1;         ///< wave_maxima: reduction blocks of the global particle ids (-1: not counted yet)
  double darcy_ = 0.0, averaged_ = 0.0, boundary_work_ = 0.0, rank_work_ = 0.0;
  std::vector<double> around_;  ///< per node: the occupied lattice cells beside it (count_occupied)
  std::vector<double> corner_;  ///< distributed_means: per node and corner slot, sum V dp and sum V
  std::vector<double> means_;   ///< distributed_means: per particle
  std::vector<double> pbar_;      ///< per node: the free water's pressure of this step (drained nodes)
  LiquidTotals<D> totals_; ///< the sums of the step's last pass (totals_ready_)
  bool totals_ready_ = false;
  /// cell_ holds the lattice cells of the particles' positions: the step's
  /// last pass found them, and nothing has moved the particles since
  /// (find_surface takes them; forget_cells).
  bool cells_ready_ = false;
};

extern template class TwoPhase<1>;
extern template class TwoPhase<2>;
extern template class TwoPhase<3>;

} // namespace otmpm
