#pragma once
/// \file engine.hpp
/// The particle-node engine (design.md points 1-4): one step loop, templated
/// on the dimension D, shared by every basis family, every integrator and both
/// node modes. `mpm`: the nodes are a fixed Eulerian grid. `ul`: the nodes are
/// advected with the increment that moves the particles (advect_nodes), and the
/// basis is recomputed on the moved nodes each step. That is the only place the
/// two modes differ.
#include "otmpm/basis/basis.hpp"
#include "otmpm/engine/mass_matrix.hpp"
#include "otmpm/engine/timers.hpp"
#include "otmpm/materials/material.hpp"
#include "otmpm/particles/particles.hpp"
#include "otmpm/reference/exact.hpp"
#include "otmpm/scene/scene.hpp"

#include <functional>
#include <memory>

namespace otmpm {

struct Checkpoint;

enum class NodeMode { mpm, ul };
enum class Integrator { fe, musl, npc, otm, unified };

Integrator parse_integrator(const std::string& name);
std::string to_string(Integrator integrator);

/// Nodal fields of one step. m: lumped mass m_I; q: momentum; v: velocity
/// (after the nodal update); v_pred: NPC predictor; f: force f_I (internal +
/// body + traction); a: acceleration; dx: the increment that moves the nodes in
/// `ul` mode (and the particles); reaction: Dirichlet reaction forces.
template <int D> struct NodalFields {
  std::vector<double> m;
  AlignedVector<Vec<D>> q, v, f, a, dx, reaction;
  std::vector<char> active;
  void resize(int n);
};

/// A Dirichlet node set: node ids and, per component, fixed flag and value.
template <int D> struct Dirichlet {
  std::vector<int> node;
  std::vector<std::array<bool, 3>> fix;
  std::vector<Vec3> value;
};

/// A traction load on a set of particles: force per unit reference area
/// `value * g(t)` (or a built-in history), area A_p = V0_p / l_p[axis].
template <int D> struct TractionLoad {
  std::vector<int> particle;
  Vec<D> value = Vec<D>::Zero();
  TimeFunction time;
  std::function<double(double)> history; ///< replaces value[axis] * g(t) when set
  int axis = 0;
};

/// Values of the time functions: constant 1, or the ramp of molinos eq. 45,
/// 0.5 (sin(2 pi t / T - pi/2) + 1) for t <= T/2 and 1 afterwards.
double time_function(const TimeFunction& g, double t);

/// What the fused particle-to-node map carries, all from one pass over the
/// basis table (molinos Algorithm 1 steps 1-2 and 4-5, wobbes Algorithm 1
/// step 1): m_I = sum_p N_Ip m_p; q_I = sum_p N_Ip m_p (w_p + c a_p); f_I =
/// sum_p (-V_p sigma_p grad N_Ip + N_Ip f_ext,p(t)). A null `w` skips the
/// momentum. With `stress_from` set, each particle first gets its
/// constitutive update (sect. 4) from dt L_p = dt sum_I v_I (x) grad N_Ip,
/// v = *stress_from, and then carries its updated V_p sigma_p: the stress
/// update of NPC in the pass that computes the forces. Its time then counts
/// in the to_nodes phase, as the fe update counts in to_particles.
template <int D> struct ToNodes {
  bool mass = false;
  const AlignedVector<Vec<D>>* w = nullptr;
  double c = 0.0;
  const AlignedVector<Vec<D>>* a = nullptr;
  bool forces = false;
  double t = 0.0;
  const AlignedVector<Vec<D>>* stress_from = nullptr;
  double dt = 0.0;
};

/// What the fused node-to-particle map does, all from one pass over the basis
/// table: v_p += c_rate sum_I N_Ip r_I (the interpolated r also stored in
/// rate_out when given); x_p += c_move sum_I N_Ip u_I; and, when `grad` is
/// set, the constitutive update with dt L_p = c_grad sum_I g_I (x) grad N_Ip.
template <int D> struct ToParticles {
  const AlignedVector<Vec<D>>* rate = nullptr;
  double c_rate = 0.0;
  AlignedVector<Vec<D>>* rate_out = nullptr;
  const AlignedVector<Vec<D>>* move = nullptr;
  double c_move = 0.0;
  const AlignedVector<Vec<D>>* grad = nullptr;
  double c_grad = 0.0;
};

/// Per-node partial sums of the particle-to-node map (mass, momentum, force).
template <int D> struct NodeSums {
  double m = 0.0;
  Vec<D> q = Vec<D>::Zero();
  Vec<D> f = Vec<D>::Zero();
};

/// Particles per scatter block, and the largest total of block node ranges
/// (in units of the node count) for which the blocked scatter is used.
constexpr int scatter_block = 8192;
constexpr int max_block_overlap = 2;

/// Energies of the runaway monitor and of the energy balance: kinetic and
/// strain energy E = kinetic + strain, the work W_ext of the external forces
/// (body force, traction; trapezoidal rule over each step) and the work W_R of
/// the Dirichlet reactions (sum over constrained node components of
/// reaction * prescribed velocity * dt: zero for fixed supports) since t = 0,
/// and E(0).
struct EnergyBalance {
  double kinetic = 0, strain = 0, external_work = 0, reaction_work = 0, initial = 0;
  double total() const { return kinetic + strain; }
  /// Work done on the body since t = 0: W_ext + W_R.
  double work() const { return external_work + reaction_work; }
  /// E(t) - E(0) - W_ext(t) - W_R(t): zero for an exact, energy-conserving
  /// solution; negative when the scheme dissipates, positive when it creates energy.
  double balance_error() const { return total() - initial - work(); }
};

template <int D> class Engine {
public:
  /// Builds the engine for a validated scene: node set (grid over the scene's
  /// grid in `mpm`; over the bodies' bounding box in `ul`), basis, particles,
  /// materials, Dirichlet sets, loads. Checks the scene first
  /// (validate_scene(scene, D): dimension == D, at least one body and
  /// material, body materials defined, cells >= 1, finite grid bounds, ...)
  /// and throws InputError naming the key when a value or the combination is
  /// not allowed, also for a Scene built in code.
  explicit Engine(const Scene& scene);
  ~Engine();

  /// Advances one step of size dt() with the scene's integrator.
  void step();
  /// Time step from the CFL condition (spec sect. 5), or the fixed dt.
  double stable_dt() const;

  const Scene& scene() const { return scene_; }
  Particles<D>& particles() { return P_; }
  const Particles<D>& particles() const { return P_; }
  const Basis<D>& basis() const { return *basis_; }
  Basis<D>& basis() { return *basis_; }
  const NodalFields<D>& nodal() const { return nodal_; }
  const BasisTable<D>& table() const { return table_; }
  const std::vector<Material>& materials() const { return materials_; }
  const Dirichlet<D>& dirichlet() const { return dirichlet_; }
  NodeMode mode() const { return mode_; }
  Integrator integrator() const { return integrator_; }
  double time() const { return t_; }
  long steps() const { return step_; }
  double last_dt() const { return dt_; }
  PhaseTimers& timers() { return timers_; }
  const EnergyBalance& energy() const { return energy_; }
  /// Sum of the Dirichlet reaction impulses since t = 0 (per component).
  const Vec<D>& reaction_impulse() const { return reaction_impulse_; }
  /// True when the last particle-to-node map used the blocked scatter, false
  /// when it used the gather over node columns (see scatter()).
  bool scatter_blocked() const { return blocks_.compact; }
  /// Total momentum sum_p m_p v_p.
  Vec<D> momentum() const;
  /// Recomputes the kinetic and strain energy (and the wave speed of the next dt).
  void update_energy();
  /// Throws InstabilityError when kinetic + strain energy exceeds
  /// energy_limit * (initial energy + |external work| + |reaction work| +
  /// sum_constrained 1/2 m_I v_prescribed^2) (runaway).
  void check_energy() const;

  /// Saves the state that evolves from step to step - particles, t, step,
  /// dt, dt_prev, external power, wave speed, energies, reaction impulse,
  /// phase timers, node positions and the basis family's own state - into
  /// groups "engine", "particles", "nodes" and "basis" of a checkpoint
  /// (engine_state.cpp; state added to the engine must be added there).
  void save_state(Checkpoint& out) const;
  /// Restores what save_state wrote into an engine freshly built from the
  /// same scene: the run then continues bit for bit. Throws InputError naming
  /// the checkpoint file when its content does not fit this engine.
  void restore_state(const Checkpoint& in);

  // ---- stages of the step (spec algorithms.md sect. 3), used by the integrators
  void evaluate_basis();
  void project_mass();
  /// q_I = sum_p N_Ip m_p w_p for a particle field w (v_p, or v_p + c a_p).
  void project_momentum(const AlignedVector<Vec<D>>& w, double c, const AlignedVector<Vec<D>>* a);
  /// f_I = sum_p (-V_p sigma_p grad N_Ip + N_Ip m_p b_p(t)) + traction(t).
  void compute_forces(double t);
  /// Solves M y = r (lumped: division by m_I; consistent: sparse solve) on
  /// active nodes; inactive nodes get zero.
  void solve_mass(const AlignedVector<Vec<D>>& r, AlignedVector<Vec<D>>& y);
  /// Sets fixed components of a nodal velocity-like field to their value.
  void apply_dirichlet_velocity(AlignedVector<Vec<D>>& v) const;
  /// Zeroes fixed components of f and stores them as reactions; adds their
  /// impulse dt R to reaction_impulse() and their work dt R . v_prescribed to
  /// energy().reaction_work.
  void apply_dirichlet_force(AlignedVector<Vec<D>>& f);
  /// L_p = sum_I v_I (x) grad N_Ip, then the constitutive update (sect. 4).
  void update_stress(const AlignedVector<Vec<D>>& v_nodes, double dt);
  /// F_p = G_p F_p with G_p = I + sum_I dx_I (x) grad N_Ip, V_p, rho_p, stress
  /// (OTM and unified: the increment instead of dt L_p).
  void update_stress_from_increment(const AlignedVector<Vec<D>>& dx);
  /// The fused particle-to-node map (see ToNodes); mass first sets the
  /// active nodes and assembles the consistent mass matrix when used.
  /// Throws InstabilityError for the lowest particle whose stress update
  /// fails (with `stress_from`), as update_stress().
  void to_nodes(const ToNodes<D>& what);
  /// The fused node-to-particle map (see ToParticles).
  void to_particles(const ToParticles<D>& what);
  /// Power of the external loads sum_p (m_p b_p(t) + t_p A_p) . v_p.
  double external_power(double t) const;
  /// Interpolates a nodal field to particles: out_p = sum_I N_Ip y_I.
  void interpolate(const AlignedVector<Vec<D>>& y, AlignedVector<Vec<D>>& out) const;
  /// The nodal field y at particle p: sum_I N_Ip y_I (table order).
  Vec<D> interpolate(int p, const AlignedVector<Vec<D>>& y) const {
    Vec<D> s = Vec<D>::Zero();
    for (int e = table_.begin(p); e < table_.end(p); ++e) s += table_.N[e] * y[table_.node[e]];
    return s;
  }
  /// x_I += dx_I in `ul` mode (no-op in `mpm`): the node-mode switch.
  void advect_nodes(const AlignedVector<Vec<D>>& dx);
  /// Throws InstabilityError (check_particle) for the first particle, in
  /// `mpm` mode, that is not finite, outside the grid or about to leave it.
  void check_particles_inside() const;

private:
  void build_nodes_and_basis();
  void build_dirichlet();
  void build_tractions();
  /// The checks of particle p: finite position, velocity and stress; in
  /// `mpm` mode inside the grid, and not about to leave it in the next step.
  void check_particle(int p) const;
  /// One pass after each step: check_particle() for every particle, the
  /// energies and the wave speed for the next stable_dt().
  void after_step();
  /// The pass of after_step() and update_energy(): kinetic and strain energy,
  /// the wave speed max_p max(c_p, |v_p|) and the momentum sum_p m_p v_p
  /// (momentum_), with the particle checks when `check` is set.
  void sum_particles(bool check);
  /// external_power(t) with the particles' momentum sum_p m_p v_p given (it
  /// is read only for a uniform body force).
  double external_power(double t, const Vec<D>& momentum) const;
  /// The uniform body force b g(t) of the scene at time t.
  Vec<D> body_force_at(double t) const;
  /// The particle-to-node sum: update(p0, p1) runs a per-particle update
  /// (or nothing) on particles [p0, p1), each particle once and before its
  /// prep; clear(I0, I1) zeroes the nodal fields of nodes [I0, I1); then for
  /// every basis table entry e (particle p, node I) add(acc_I, e, prep(p)),
  /// and merge(I, acc_I) adds acc_I into the nodal fields. Particles are cut
  /// into fixed blocks of scatter_block; each block sums in particle order
  /// into its own node range, and each node adds the block sums in block
  /// order - the same bits for any thread count. Threads own node ranges for
  /// clear and merge, so no node loop is serial. When the block ranges
  /// overlap too much (particles not spatially ordered), a gather over the
  /// transposed table (gather_columns) does it instead, after updating all
  /// particles (it calls prep once per entry).
  template <class Update, class Prep, class Add, class Merge, class Clear>
  void scatter(Update&& update, Prep&& prep, Add&& add, Merge&& merge, Clear&& clear);
  /// Phase 1 of scatter() for block b: update() on the block's particles,
  /// then their sums into the block's buffer (the block's table rows, read
  /// by both, partly still in cache; measured: updating smaller batches
  /// between their sums is slower, the two access streams interfere).
  template <class Update, class Prep, class Add> void scatter_block_sums(int b, Update& update, Prep& prep, Add& add);
  template <class Update, class Prep, class Add, class Merge, class Clear>
  void gather_columns(Update&& update, Prep&& prep, Add&& add, Merge&& merge, Clear&& clear);
  /// Node ranges of the scatter blocks for the current basis table.
  void plan_scatter();
  template <bool Mass, bool Momentum, bool Forces> void to_nodes_impl(const ToNodes<D>& what);
  /// The particles' external forces at time t into fext_ (when they are not
  /// the uniform body force m_p b(t), which to_nodes computes inline).
  void prepare_external_forces(double t);
  void finish_mass();
  /// Strain, density, volume and stress update of particle p from H = dt L_p.
  void update_particle_stress(int p, const Mat<D>& H);
  /// update_particle_stress for particles [p0, p1) with dt L_p = dt sum_I
  /// v_I (x) grad N_Ip (serial; the callers thread it).
  void update_stress_range(const AlignedVector<Vec<D>>& v_nodes, double dt, int p0, int p1);
  /// Allocates the optional particle fields this scene reads and drops
  /// length0 when no traction needs it (memory).
  void allocate_fields();
  /// Calls visit(p, force) for every external force on a particle at time t.
  template <class Visit> void for_each_external_force(double t, Visit&& visit) const;
  [[noreturn]] void unstable(int p, const std::string& what) const;

  Scene scene_;
  NodeMode mode_ = NodeMode::mpm;
  Integrator integrator_ = Integrator::npc;
  std::unique_ptr<Basis<D>> basis_;
  std::unique_ptr<MassMatrix<D>> mass_matrix_;
  Particles<D> P_;
  std::vector<Material> materials_;
  bool any_finite_strain_ = false;
  NodalFields<D> nodal_;
  BasisTable<D> table_;
  NeighbourLists<D> neighbours_; ///< Verlet lists of the particles (families that search nodes)
  NodeColumns columns_;          ///< transposed table_, for gather_columns
  bool columns_valid_ = false;
  struct ScatterBlocks {
    std::vector<int> lo, hi, offset; ///< node range of each block, start in buffer
    AlignedVector<NodeSums<D>> buffer;
    bool valid = false, compact = false;
  } blocks_;
  AlignedVector<Vec<D>> fext_;   ///< external force per particle (tractions, manufactured body force)
  bool uniform_body_force_ = false;
  double wave_speed_ = 0.0;      ///< max_p max(c_p, |v_p|) after the last step
  Vec<D> momentum_ = Vec<D>::Zero(); ///< sum_p m_p v_p after the last step (= momentum())
  std::vector<double> p_modulus_; ///< per material: P-wave modulus for D
  Dirichlet<D> dirichlet_;
  /// The distinct nodes of dirichlet_.node, ascending (reaction bookkeeping).
  std::vector<int> dirichlet_nodes_;
  /// constrained[I*D + k]: component k of node I is fixed (consistent mass).
  std::vector<char> constrained_;
  std::vector<TractionLoad<D>> tractions_;
  Vec<D> body_force_ = Vec<D>::Zero();
  bool has_body_force_ = false;
  std::unique_ptr<ExactSolution<D>> exact_; ///< for a manufactured body force
  Vec<D> grid_h_ = Vec<D>::Ones();
  double h_min0_ = 1.0, node_spacing0_ = 1.0;
  Vec<D> domain_lower_, domain_upper_;
  double t_ = 0.0, dt_ = 0.0, dt_prev_ = 0.0;
  long step_ = 0;
  PhaseTimers timers_;
  EnergyBalance energy_;
  Vec<D> reaction_impulse_ = Vec<D>::Zero();
  double external_power_ = 0.0; ///< power of the external loads at t_ (trapezoidal work)

  template <int E> friend void step_fe(Engine<E>&, bool musl);
  template <int E> friend void step_npc(Engine<E>&);
  template <int E> friend void step_otm(Engine<E>&);
  template <int E> friend void step_unified(Engine<E>&);
};

/// One step of each integrator (integrators/*.cpp), reading like the
/// algorithm listings of spec algorithms.md sect. 3.
template <int D> void step_fe(Engine<D>& e, bool musl);
template <int D> void step_npc(Engine<D>& e);
template <int D> void step_otm(Engine<D>& e);
template <int D> void step_unified(Engine<D>& e);

extern template class Engine<1>;
extern template class Engine<2>;
extern template class Engine<3>;

} // namespace otmpm
