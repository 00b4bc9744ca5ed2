#pragma once
/// \file engine.hpp
/// The particle-node engine: one step loop, templated on the dimension D,
/// shared by every basis family, every integrator and both node modes. It is
/// built from typed parts (EngineParts: nodes and basis, node mode,
/// particles, materials, constraints, loads, step settings) - from a scene
/// by the assembler (assembly/assembler.hpp), or by hand in C++ - and steps
/// them with the integrator's step function, which drives the public stages
/// below (evaluate_basis, to_nodes, solve_mass, to_particles, advect_nodes).
/// The engine knows no scene, no benchmark and no integrator by name.
#include "otmpm/basis/basis.hpp"
#include "otmpm/engine/after_step.hpp"
#include "otmpm/engine/constraints.hpp"
#include "otmpm/engine/contact.hpp"
#include "otmpm/engine/distribution.hpp"
#include "otmpm/engine/loads.hpp"
#include "otmpm/engine/mass_matrix.hpp"
#include "otmpm/engine/node_mode.hpp"
#include "otmpm/engine/rows.hpp"
#include "otmpm/engine/side_walls.hpp"
#include "otmpm/engine/step.hpp"
#include "otmpm/engine/timers.hpp"
#include "otmpm/engine/two_phase.hpp"
#include "otmpm/engine/volumetric.hpp"
#include "otmpm/engine/wall_transfer.hpp"
#include "otmpm/materials/material.hpp"
#include "otmpm/particles/particles.hpp"

#include <functional>
#include <memory>
#include <optional>
#include <vector>

namespace otmpm {

struct Checkpoint;

template <int D> class ParticleToNodes; // the particle-to-node map, engine/scatter.hpp
template <int D> class ChannelWalls;    // a channel's side walls in a run, engine/channel_walls.hpp

/// Nodal fields of one step. m: lumped mass m_I; q: momentum; v: velocity
/// (after the nodal update); f: force f_I (internal + external); a:
/// acceleration; dx: the increment that moves the particles (and the nodes
/// in `ul` mode); reaction: Dirichlet reaction forces (the force components
/// removed); active: m_I above the mass tolerance; active_nodes: the
/// active nodes, ascending (the walls' passes visit only these); visited:
/// the nodes the step's nodal loops visit, ascending (Engine::list_visited_nodes).
/// With body contact every body has its own copy: entry I + b N is node I of
/// body b's field (contact.hpp).
template <int D> struct NodalFields {
  std::vector<double> m;
  AlignedVector<Vec<D>> q, v, f, a, dx, reaction;
  std::vector<char> active;
  std::vector<int> active_nodes;
  std::vector<int> visited;
  std::vector<char> listed; ///< scratch of Engine::list_visited_nodes: per node, visited
  void resize(int n);
  /// Zeroes every field of node I (it left the visited nodes).
  void zero(int I);
};

/// A basis and its Dirichlet sets on a node lattice: a share's, built by the
/// share itself (a rank of a distributed run: on its window of the lattice
/// only), or the nodes laid out anew (NodeReset).
template <int D> struct LatticePart {
  std::unique_ptr<Basis<D>> basis;
  Dirichlet<D> dirichlet;
};

/// `ul` mode: the nodes laid out anew on the scene grid's lattice over the
/// particles when their smallest spacing has fallen below `below` h (docs/theory.md
/// sect. 3, "Node reset"); below = 0: never. The lattice lines move with the
/// boundaries that move their nodes: at time t they are the scene grid's
/// lines translated by `velocity` t, so that a held node plane stays on a line.
template <int D> struct NodeReset {
  double below = 0.0;
  CartesianGrid<D> lines; ///< the scene's grid at t = 0: the new lattice runs on its lines, with its spacing
  Vec<D> velocity = Vec<D>::Zero(); ///< per axis: the velocity of the boundaries that fix it (0: none moves)
  /// The boundary boxes that are planes normal to an axis they fix: (axis,
  /// coordinate at t = 0; it moves with `velocity`). A basis whose domain the
  /// nodes carry (B-splines) has a node on such a plane only where its
  /// lattice ends: a reset lattice ends there when the particles lie on one side.
  std::vector<std::pair<int, double>> planes;
  /// The basis and Dirichlet sets on a lattice laid out at time t (the boundary boxes moved with them).
  std::function<LatticePart<D>(const CartesianGrid<D>&, double t)> lattice;
  /// The lines at time t: `lines` translated by velocity t.
  CartesianGrid<D> lines_at(double t) const {
    CartesianGrid<D> g = lines;
    for (int k = 0; k < D; ++k) {
      g.lower[k] += velocity[k] * t;
      g.upper[k] += velocity[k] * t;
    }
    return g;
  }
};

/// What the node resets of a run have left (NodeReset): how many, when the
/// last was, the lattice it laid the nodes out on, and each particle's home -
/// the cell of that lattice that held it then: its F-bar patch until the next
/// reset, and in a distributed run the cell whose rank holds it
/// (Domain::lay_out). Checkpointed as cells of that lattice, so that a
/// restart divides the particles on any rank count.
template <int D> struct LaidOutLattice {
  long resets = 0;
  double time = 0.0;                    ///< of the last reset (where the moving boundary boxes were)
  std::optional<CartesianGrid<D>> grid; ///< none before the first reset
  std::vector<Index<D>> home;
  bool homes = false; ///< home holds every particle's (not so after a restart from a checkpoint without them)
};

/// How the engine steps: the integrator's step function and parameters,
/// the time step rule (CFL with the P-wave speed, docs/theory.md
/// sect. 10, or a fixed dt), the mass matrix and the run's limits.
template <int D> struct StepSettings {
  IntegratorStep<D> step; ///< the integrator: its step function and what it needs
  IntegratorParameters parameters;
  double t_end = 0.0;
  double cfl = 0.1;
  std::optional<double> dt;      ///< fixed step instead of the CFL rule
  double h = 0.0;                ///< initial nodal spacing h of the CFL condition (smallest axis)
  bool consistent_mass = false;  ///< solve with M_IJ instead of dividing by m_I
  double mass_tolerance = 1e-12; ///< nodes with m_I <= tol max m are inactive
  double energy_limit = 10.0;    ///< runaway monitor factor (check_energy)
  /// The volumetric part of each particle's dF: its own, or its patch's (F-bar, volumetric.hpp).
  Volumetric volumetric = Volumetric::none;
  /// F-bar: the lattice whose cells are the patches (the scene's node lattice:
  /// the grid in `mpm`, the initial lattice in `ul`); unset: the nodes' own.
  std::optional<CartesianGrid<D>> patch_grid;
  NodeReset<D> node_reset;
  /// The liquid phase of saturated bodies that the step function drives
  /// (engine/two_phase.hpp), or null (a dry run): built by the engine from
  /// EngineParts::two_phase.
  std::shared_ptr<TwoPhase<D>> two_phase;
};

/// Everything an engine is built from.
template <int D> struct EngineParts {
  std::unique_ptr<Basis<D>> basis; ///< owns the node set
  NodeMode<D> mode = NodeMode<D>::advected();
  Particles<D> particles;
  std::vector<std::unique_ptr<Material<D>>> materials; ///< indexed by Particles::material
  Dirichlet<D> dirichlet;
  std::vector<Wall<D>> walls;
  Loads<D> loads;
  StepSettings<D> settings;
  /// This rank's part in a distributed run (distributed/domain.hpp); null
  /// in a serial run. The other parts are then this rank's share: the
  /// particles of its cells and the nodes of its window.
  std::shared_ptr<Distribution<D>> distribution;
  /// Body-body contact (fixed grid, lumped mass); without it the bodies
  /// share one nodal field. Ignored when the particles belong to one body.
  std::optional<ContactLaw> contact;
  /// The liquid phase of saturated bodies (two_phase.hpp; fixed grid, lumped mass).
  std::optional<TwoPhaseParts<D>> two_phase;
  /// A channel's side walls on a plane-strain body (D = 2; side_walls.hpp).
  std::optional<SideWalls> side_walls;
};

/// The energies of the runaway monitor and of the energy balance
/// (docs/theory.md eq. 11.1): kinetic and stored (elastic) energy, the
/// energy the materials dissipated (plastic work W_p), the energy Coulomb
/// friction dissipated at the walls and in the body contact (W_f), the
/// energy impacts took there (W_i: the normal approach the walls and the
/// contact stopped, eq. 6.5), the
/// energy the Darcy drag of saturated bodies dissipated (W_d, eq. 15.6), the
/// pore pressure's work on the increments its cell average leaves out (W_a,
/// eq. 15.13), the kinetic energy the PIC relaxation of the particle
/// velocities took (W_v, ToParticles::pic), the
/// work W_ext of the external loads and W_R of the Dirichlet reactions and
/// the walls since t = 0, and E(0). With saturated bodies the kinetic and
/// stored energies include the liquid's.
struct EnergyBalance {
  double kinetic = 0, strain = 0, dissipated = 0, external_work = 0, reaction_work = 0, initial = 0;
  double friction = 0, darcy = 0, impact = 0, pressure_average = 0, relaxation = 0;
  double total() const { return kinetic + strain; }
  /// Work done on the body since t = 0: W_ext + W_R.
  double work() const { return external_work + reaction_work; }
  /// The energy spent since t = 0: W_p + W_f + W_i + W_d + W_a + W_v.
  double spent() const { return dissipated + friction + darcy + impact + pressure_average + relaxation; }
  /// E(t) + W_p(t) + W_f(t) + W_i(t) + W_d(t) + W_a(t) + W_v(t) - E(0) - W(t): zero for an exact solution;
  /// negative when the scheme dissipates, positive when it creates energy.
  double balance_error() const { return total() + spent() - initial - work(); }
};

/// What the fused particle-to-node map carries, all from one pass over the
/// basis table (molinos et al. Algorithm 1 steps 1-2 and 5, wobbes et al.
/// Algorithm 1 step 1): m_I = sum_p N_Ip m_p; q_I = sum_p N_Ip m_p (w_p + c
/// a_p) (null w: no momentum); f_I = sum_p (-V_p sigma_p grad N_Ip + N_Ip
/// f_ext,p(t)) (forces; with F-bar sigma_eff,p of docs/theory.md eq. 9.10).
/// `split` (with w and a, without forces): q_I =
/// sum_p N_Ip m_p w_p and f_I = sum_p N_Ip m_p a_p apart. `liquid` (with
/// the mass, w and forces): the liquid's sums of the step in the same pass
/// (TwoPhase::scatter_with).
template <int D> struct ToNodes {
  bool mass = false;
  const AlignedVector<Vec<D>>* w = nullptr;
  double c = 0.0;
  const AlignedVector<Vec<D>>* a = nullptr;
  bool forces = false;
  double t = 0.0;
  bool split = false;
  TwoPhase<D>* liquid = nullptr;
};

/// What the fused node-to-particle map does, all from one pass over the
/// basis table: v_p += c_rate sum_I N_Ip r_I (the interpolated r also stored
/// in rate_out when given) + sum_I N_Ip k_I (k: kick, a velocity change
/// not kept in rate_out; only with a rate and a move); x_p += c_move sum_I
/// N_Ip u_I. `liquid` (with a rate and a move; TwoPhase::begin_rows first):
/// the liquid's update of each particle (TwoPhase::finish_rows) in the same
/// pass, after the particle's stress update.
template <int D> struct ToParticles {
  const AlignedVector<Vec<D>>* rate = nullptr;
  double c_rate = 0.0;
  AlignedVector<Vec<D>>* rate_out = nullptr;
  const AlignedVector<Vec<D>>* kick = nullptr;
  const AlignedVector<Vec<D>>* move = nullptr;
  double c_move = 0.0;
  TwoPhase<D>* liquid = nullptr;
  /// PIC relaxation after the pass: v_p += pic_share (sum_I N_Ip pic_I -
  /// v_p) (pic: the nodal velocities at the step's end; share in (0, 1]),
  /// the kinetic energy it removes booked as W_v (EnergyBalance::relaxation).
  const AlignedVector<Vec<D>>* pic = nullptr;
  double pic_share = 0.0;
  /// True when the pass is followed by the PIC relaxation.
  bool relaxes() const { return pic && pic_share > 0.0; }
  /// The step's last change to the particles (nothing after it moves them
  /// or changes their state): the engine takes the after-step sums and
  /// checks of each block of particles right after the block's update
  /// (after_step.hpp) - the same bits as the sweep after the step, which it
  /// saves. Not with a PIC relaxation or the liquid of saturated bodies.
  /// fe, npc and central_difference mark it; integrators whose last pass
  /// updates the stress alone (musl, explicit_alpha, otm) leave the sums to
  /// the sweep, which was measured faster there (docs/performance-log-2026.md).
  bool last = false;
};

/// A nodal field g with a factor c whose gradient drives the constitutive
/// update: H_p = c sum_I g_I (x) grad N_Ip (c = dt with nodal velocities,
/// 1 with nodal increments).
template <int D> struct Gradient {
  const AlignedVector<Vec<D>>* field = nullptr;
  double c = 0.0;
};

template <int D> class Engine {
public:
  /// Builds the engine from its parts: binds the basis to the particles and
  /// the materials to their state, allocates the nodal fields, takes the
  /// initial energy and wave speed. std::invalid_argument when the parts do
  /// not fit together (no basis or step function, a particle of a material
  /// that is not there, a constraint on a node that does not exist, ...);
  /// InstabilityError when the initial state is not finite.
  explicit Engine(EngineParts<D> parts);
  Engine(Engine&&) noexcept;
  ~Engine();

  /// Advances one step of size stable_dt() with the integrator's step function.
  void step();
  /// Time step from the CFL condition or the fixed dt, at most t_end - t.
  double stable_dt() const;
  /// The fastest signal of the CFL condition: max_p max(c_p, |v_p|) of all particles (all ranks).
  double wave_speed() const { return wave_speed_; }

  Particles<D>& particles() { return P_; }
  const Particles<D>& particles() const { return P_; }
  Basis<D>& basis() { return *basis_; }
  const Basis<D>& basis() const { return *basis_; }
  NodalFields<D>& nodal() { return nodal_; }
  const NodalFields<D>& nodal() const { return nodal_; }
  /// The step's basis table (built from its compact rows on the first call: StepRows);
  /// with body contact its node ids are field nodes, I + body_p N (contact.hpp).
  const BasisTable<D>& table() const { return rows_.full(); }
  /// table().entries(), sum over p of the nodes of N_Ip, without building the table.
  std::size_t basis_entries() const { return rows_.entries(); }
  /// The body contact, or null when the bodies share one nodal field.
  const BodyContact<D>* contact() const { return contact_.get(); }
  const Material<D>& material(int i) const { return *materials_[static_cast<std::size_t>(i)]; }
  int material_count() const { return static_cast<int>(materials_.size()); }
  const Dirichlet<D>& dirichlet() const { return constraints_.dirichlet(); }
  const std::vector<Wall<D>>& walls() const { return constraints_.walls(); }
  /// The impulse each wall gave the body since t = 0.
  const AlignedVector<Vec<D>>& wall_impulse() const { return constraints_.wall_impulse(); }
  const Loads<D>& loads() const { return loads_; }
  Loads<D>& loads() { return loads_; }
  /// This rank's part in a distributed run, or null.
  Distribution<D>* distribution() const { return dist_.get(); }
  const NodeMode<D>& mode() const { return mode_; }
  const StepSettings<D>& settings() const { return settings_; }
  double time() const { return t_; }
  long steps() const { return step_; }
  double last_dt() const { return dt_; }
  /// `ul` mode: how often the nodes were laid out anew (NodeReset) since t = 0.
  long node_resets() const { return laid_out_.resets; }
  PhaseTimers& timers() { return timers_; }
  const EnergyBalance& energy() const { return energy_; }
  /// True when friction and impacts may take energy (energy().friction, energy().impact): walls or body contact.
  bool has_friction() const { return !constraints_.walls().empty() || contact_ || channel_; }
  /// Sum of the Dirichlet reaction impulses since t = 0 (per component): the
  /// momentum the Dirichlet sets gave the particles.
  const Vec<D>& reaction_impulse() const { return reaction_impulse_; }
  /// True when the last particle-to-node map used the blocked scatter, false
  /// when it gathered over node columns (ParticleToNodes).
  bool scatter_blocked() const;
  /// Total momentum sum_p m_p v_p.
  Vec<D> momentum() const;
  /// Recomputes the energies (and the wave speed of the next dt).
  void update_energy();
  /// Throws InstabilityError when kinetic + stored energy exceeds
  /// energy_limit * (E(0) + |W_ext| + |W_R| + the kinetic energy of the
  /// prescribed nodal velocities) (runaway).
  void check_energy() const;
  /// Throws InstabilityError for the first particle that is not finite or,
  /// on the fixed grid, outside it or about to leave it.
  void check_particles_inside() const;

  /// Saves what evolves from step to step (particles and their material
  /// state, clock, energies, node positions, the basis' state) into groups
  /// "engine", "particles", "nodes" and "basis" (engine_state.cpp).
  void save_state(Checkpoint& out) const;
  /// Restores what save_state wrote into an engine built from the same
  /// parts: the run then continues bit for bit. InputError naming the
  /// checkpoint when its content does not fit.
  void restore_state(const Checkpoint& in);

  // ---- the stages of a step, driven by the integrators (docs/theory.md)
  /// The basis at the particles' positions, once per step, into table()
  /// (exactly once: Basis::evaluate_points counts its calls as steps).
  void evaluate_basis();
  /// The fused particle-to-node map (ToNodes); with `mass` also the active
  /// nodes and, with the consistent mass, M_IJ assembled and factorised.
  void to_nodes(const ToNodes<D>& what);
  /// The constitutive update from `g` (docs/theory.md
  /// sect. 9) in the same pass as to_nodes(what): each block of particles
  /// is updated, then scatters its new V_p sigma_p (molinos et al. Algorithm 1
  /// stages 4-5; with F-bar every particle first). InstabilityError for the lowest failing particle.
  void update_stress_and_to_nodes(const Gradient<D>& g, const ToNodes<D>& what);
  /// Solves M y = r (lumped: division by m_I; consistent: sparse solve) on
  /// active nodes; inactive nodes get zero, and the fixed components of
  /// active nodes r_Ik / m_I (what the lumped mass gives them). With the
  /// consistent mass the constrained rows couple to the free ones: when the
  /// particles' velocities take up y times c (c > 0), their inertial
  /// reaction rho_Ik = sum_{J free} M_IJ y_Jk is booked as a Dirichlet
  /// reaction (impulse c rho, work c rho vbar), so that the reaction impulse
  /// is the momentum the particles get.
  void solve_mass(const AlignedVector<Vec<D>>& r, AlignedVector<Vec<D>>& y, double c = 0.0);
  /// solve_mass(r, y, c), then v += s y - or, with `q`, v = M^{-1} q + s y;
  /// with the lumped mass in one pass over the nodes (the same bits as the separate calls).
  void solve_mass_add(const AlignedVector<Vec<D>>& r, AlignedVector<Vec<D>>& y, double c,
                      AlignedVector<Vec<D>>& v, double s, const AlignedVector<Vec<D>>* q = nullptr);
  /// Sets the fixed components of a nodal velocity-like field to their value,
  /// corrects the velocities of bodies in contact (BodyContact::apply) and
  /// applies the rigid walls (Constraints::apply_walls) at the nodes'
  /// current positions; `effect` says how a change reaches the particles
  /// (and whether it is booked: reaction impulse and work, wall impulses,
  /// the energy friction takes).
  void constrain_velocity(AlignedVector<Vec<D>>& v, const WallEffect<D>& effect = {});
  /// Zeroes the fixed components of an acceleration-like field, noting the
  /// momentum removed for book_carried.
  void constrain_rate(AlignedVector<Vec<D>>& r) { constraints_.zero_carried(r, nodal_.m); }
  /// After a Booking::held pass: Constraints::book_held on the nodal f and
  /// q, which becomes the held nodes' kick.
  void book_held(const AlignedVector<Vec<D>>& rate);
  /// After a Booking::carried pass on v, a from a_n (Constraints and BodyContact::book_carried).
  void book_carried(double alpha_m, double gamma, bool first, const AlignedVector<Vec<D>>& a_n);
  /// The Dirichlet sets' (dx = dt vbar), the contact's and the walls' rules
  /// on the node increments dx of this step.
  void constrain_increment(AlignedVector<Vec<D>>& dx) const;
  /// Zeroes fixed components of f, stores them as reactions and books their
  /// impulse c R and work c R vbar (energy().reaction_work), where c is the
  /// factor with which the particles' velocities take up f / m.
  void apply_dirichlet_force(AlignedVector<Vec<D>>& f, double c);
  /// The fused node-to-particle map (ToParticles).
  void to_particles(const ToParticles<D>& what);
  /// to_particles(move), then to_nodes(what) from the updated particles, in
  /// one pass over the table (each block of particles is moved, then
  /// scattered): the musl remap of the new momenta. `what` may not ask for
  /// the mass. The same bits as the two calls.
  void to_particles_then_to_nodes(const ToParticles<D>& move, const ToNodes<D>& what);
  /// to_particles(what) and, in the same pass, the constitutive update from `g`.
  void to_particles_and_update_stress(const ToParticles<D>& what, const Gradient<D>& g);
  /// The constitutive update from `g` alone (its own pass).
  void update_stress(const Gradient<D>& g);
  /// Interpolates a nodal field to particle p: sum_I N_Ip y_I (table order).
  Vec<D> interpolate(int p, const AlignedVector<Vec<D>>& y) const;
  /// x_I += dx_I in `ul` mode, nothing on the fixed grid (NodeMode::advect);
  /// a light node moves with its material (docs/theory.md eq. 3.1).
  void advect_nodes(const AlignedVector<Vec<D>>& dx);
  /// Power of the body force sum_p m_p b(X_p, t) . v_p (the tractions'
  /// work follows the loaded particles' motion: Loads::traction_work).
  double external_power(double t) const;

  /// A distributed run rebalanced its cells: this rank's window of the node
  /// lattice changed. The basis on the new window and its Dirichlet entries
  /// replace the old ones; the per-point state of the basis (which moved
  /// with the particles) is handed over as it is. Only between steps.
  void repartition(std::unique_ptr<Basis<D>> basis, Dirichlet<D> dirichlet);

private:
  void check_parts() const;
  /// The checks of particle p: finite position, velocity and stress; on the
  /// fixed grid inside it and not about to leave it.
  void check_particle(int p) const;
  /// True when particle p passes check_particle (no message): particles_ok
  /// of p alone.
  bool particle_ok(int p) const;
  /// True when particles [p0, p1) all pass check_particle, without a branch
  /// per particle (the after-step pass's fast test): the sum of d - d over
  /// their positions, velocities and stresses is 0 exactly when every value
  /// is finite, and the box of x and x + dt v lies inside the fixed grid.
  bool particles_ok(int p0, int p1) const;
  /// After each step: check_particle() for every particle, the energies,
  /// the wave speed for the next stable_dt() and the momentum, in one pass
  /// (no checks when `check` is false).
  void sum_particles(bool check);
  /// Adds particles [p0, p1) (a sub-block of a block of sum_particles) to
  /// acc: kinetic energy, momentum, |v_p|^2 and the staying() test; false
  /// when `check` and particles_ok fails (acc's sums then go on).
  bool kinematic_sums(int p0, int p1, bool check, ParticleSums<D>& acc) const;
  /// Adds the materials' stored and dissipated energies and c_p^2 of particles [p0, p1) to acc.
  void material_sums(int p0, int p1, ParticleSums<D>& acc) const;
  /// to_particles_on over the blocks of particles, each block's sums into step_sums_ after its update
  /// (ToParticles::last).
  void to_particles_and_sum(const ToParticles<D>& what, const Gradient<D>& g);
  /// Distributed runs: every rank stops on the failing particle with the
  /// lowest global id when any rank's checks failed (`failed`).
  void agree_checks(bool failed) const;
  /// The particle-to-node pass; update(p0, p1) runs on each block of
  /// particles before it is scattered.
  template <bool Mass, bool Momentum, bool Forces, bool Split = false, class Update>
  void to_nodes_impl(const ToNodes<D>& what, Update&& update);
  /// Dispatches to_nodes_impl on what `what` asks for.
  template <class Update> void to_nodes_with(const ToNodes<D>& what, Update&& update);
  /// The node-to-particle map of `what` (and the constitutive update from
  /// `g` when Field) on particles [begin, end).
  template <bool Rate, bool Move, bool Field, bool Kick = false, bool Liquid = false>
  void to_particles_range(const ToParticles<D>& what, const Gradient<D>& g, int begin, int end);
  /// to_particles_range over the rows of `view` (rows.hpp); Liquid: ToParticles::liquid.
  template <bool Rate, bool Move, bool Field, bool Kick, bool Liquid, class View>
  void to_particles_rows(const ToParticles<D>& what, const Gradient<D>& g, int begin, int end,
                         const View view);
  /// Dispatches to_particles_range on what `what` and `g` hold.
  void to_particles_on(const ToParticles<D>& what, const Gradient<D>& g, int begin, int end);
  void finish_mass();
  void assemble_mass_matrix();
  void list_visited_nodes(); ///< NodalFields::visited for the new basis table (engine.cpp says which)
  void contact_mass_gradient(); ///< the mass gradients of the bodies' fields for the contact normals
  /// Node positions per field node (the nodes' own without contact).
  const AlignedVector<Vec<D>>& field_positions() const;
  /// The constitutive update of particles [p0, p1) from H_p = c sum_I g_I (x)
  /// grad N_Ip, in batches handed to each particle's material.
  void update_stress_range(const Gradient<D>& g, int p0, int p1);
  /// Hands H of particles [p0, p1) to their materials (runs of one material).
  void update_materials(int p0, int p1, const Mat<D>* H);
  /// F-bar (StepSettings::volumetric): H_p of every particle from `g`, averaged
  /// over the patches into hbar_, which the updates of this pass then read
  /// (true); false when the particles' own H_p apply.
  bool average_volumetric(const Gradient<D>& g);
  /// The F-bar patch of each particle (volumetric.hpp), from the positions of
  /// the basis evaluation (`mpm`) or, once, of the lattice's layout (`ul`:
  /// X on the initial lattice, the homes after a node reset).
  void assign_patches();
  double cfl_spacing() const; ///< the CFL rule's node spacing (NodeMode::cfl_spacing; the ranks' smallest)
  bool reset_due() const; ///< the nodes are to be laid out anew before this step (NodeReset; on every rank)
  /// Lays the nodes out anew on the grid's lattice over the particles (NodeReset), or on `grid` (a restart).
  void reset_nodes(const CartesianGrid<D>* grid = nullptr);
  /// gradient_ (and gradient0_ the first time) from the table just evaluated.
  void measure_gradients();
  /// Moves the particles the basis evaluated at another position into its
  /// support's hull (PointQuery::moved) to that position.
  void move_into_hull();
  /// `ul` with a family that searches its support: the nodes of the lattice
  /// cells that hold no particle at `x` (t = 0, or a node reset) are taken out
  /// of the node set (NodeSet::remove): the nodes discretise the body, not its
  /// bounding box.
  void follow_body(const AlignedVector<Vec<D>>& x);
  /// advect_nodes' increments with the light nodes' replaced (null: none is light on any rank).
  std::optional<AlignedVector<Vec<D>>> light_increments(const AlignedVector<Vec<D>>& dx);
  [[noreturn]] void unstable(int p, const std::string& what) const;
  [[noreturn]] void unstable(const std::string& what) const;
  /// A stage that may fail for a particle: in a distributed run a rank that
  /// fails defers its failure and goes on with the step; every rank stops on
  /// the failure with the lowest global particle id at the next reduction,
  /// so none waits for a rank that stopped.
  template <class Stage> void fallible(Stage&& stage);
  /// Sends the partial nodal sums of the last to_nodes to their owners and the totals back (distributed runs).
  void exchange_sums(bool mass, bool momentum, bool forces);
  /// Power of the body force at t over all ranks (`momentum`: the global sum_p m_p v_p).
  double global_power(double t, const Vec<D>& momentum) const;
  /// Books c rho, rho_Ik = sum_{J free} M_IJ y_Jk the consistent mass's
  /// inertial reaction on the fixed components, as a Dirichlet reaction.
  void book_inertial_reaction(const AlignedVector<Vec<D>>& y, double c);
  /// Where the constraints book: the run's totals, or this rank's share of the step.
  Ledger<D> ledger() {
    if (dist_) return {&rank_reaction_.impulse, &rank_reaction_.work, &rank_reaction_.friction, &rank_reaction_.impact, &rank_reaction_.relaxation};
    return {&reaction_impulse_, &energy_.reaction_work, &energy_.friction, &energy_.impact, &energy_.relaxation};
  }
  /// The particle's id in messages: its global id in a distributed run.
  long long particle_id(int p) const { return dist_ ? dist_->global_id(p) : p; }

  std::unique_ptr<Basis<D>> basis_;
  NodeMode<D> mode_;
  Particles<D> P_;
  std::vector<std::unique_ptr<Material<D>>> materials_;
  Constraints<D> constraints_;
  std::unique_ptr<BodyContact<D>> contact_;
  AlignedVector<Vec<D>> field_positions_; ///< with contact: x_I repeated per field (fixed grid)
  Loads<D> loads_;
  StepSettings<D> settings_;
  std::unique_ptr<MassMatrix<D>> mass_matrix_;
  NodalFields<D> nodal_;
  mutable StepRows<D> rows_; ///< the step's basis rows (mutable: table() builds the table on demand)
  std::unique_ptr<ParticleToNodes<D>> scatter_; ///< engine/scatter.hpp (internal: needs parallel.hpp)
  AlignedVector<Vec<D>> fext_; ///< external force per particle when not uniform
  std::unique_ptr<ChannelWalls<D>> channel_; ///< side walls (2D; engine/channel_walls.hpp)
  double node_spacing0_ = 1.0; ///< the nodes' smallest spacing at t = 0
  /// ul, searching family: max |grad N_Ip| of the first and the last table (NodeMode::cfl_spacing), 0 before
  double gradient0_ = 0.0, gradient_ = 0.0;
  AlignedVector<Vec<D>> moved_; ///< ul, searching family: the displacement into the hull (Basis::evaluate_points)
  AlignedVector<Vec<D>> x_start_; ///< ul: the particles' positions at the start of the step
  std::vector<int> light_;        ///< ul: nodes under kLightNode of the heaviest's mass (finish_mass)
  LaidOutLattice<D> laid_out_;
  FbarState<D> fbar_;
  StepSums<D> step_sums_; ///< the after-step sums of the step's last pass (ToParticles::last)
  double t_ = 0.0, dt_ = 0.0, dt_prev_ = 0.0;
  long step_ = 0;
  mutable PhaseTimers timers_; // also the const stages time themselves (constrain_increment)
  EnergyBalance energy_;
  double wave_speed_ = 0.0;          ///< max_p max(c_p, |v_p|) after the last step
  Vec<D> momentum_ = Vec<D>::Zero(); ///< sum_p m_p v_p after the last step
  Vec<D> reaction_impulse_ = Vec<D>::Zero();
  double external_power_ = 0.0, held_work_ = 0.0; ///< power of the body force at t_ (trapezoidal work); eq. 11.1c
  AlignedVector<Vec<D>> traction_start_; ///< the loaded particles' positions at the start of the step
  std::shared_ptr<Distribution<D>> dist_;
  /// A distributed run: this rank's Dirichlet impulse and work and the walls' losses of the step (summed
  /// over the ranks with the energies), and the ranks' kinetic energy of the prescribed nodal velocities.
  struct {
    Vec<D> impulse = Vec<D>::Zero();
    double work = 0.0, friction = 0.0, impact = 0.0, relaxation = 0.0;
  } rank_reaction_;
  double boundary_kinetic_ = 0.0, unresolved_work_ = 0.0; ///< unresolved: Loads::unresolved_work of the step
  WallTransfer<D> transfer_; ///< the nodes the walls changed in the step's passes (book_transfer)
  void book_transfer(const ToParticles<D>& what); ///< W_i += transfer_'s share, Delta_I = c_rate rate_I + kick_I
};

template <int D> Vec<D> Engine<D>::interpolate(int p, const AlignedVector<Vec<D>>& y) const {
  Vec<D> s = Vec<D>::Zero();
  const BasisTable<D>& t = table();
  for (int e = t.begin(p); e < t.end(p); ++e) s += t.N[e] * y[t.node[e]];
  return s;
}

/// The lattice of the last node reset (NodeReset) a checkpoint holds and the
/// time it was laid out at, or nullopt when its run laid out no node anew.
/// InputError naming the checkpoint when the lattice is not valid.
template <int D> struct ResetLattice {
  CartesianGrid<D> grid;
  double time = 0.0;
};
template <int D> std::optional<ResetLattice<D>> reset_lattice_of(const Checkpoint& ck);
/// The home cells of `n` particles a checkpoint's group "nodes" holds
/// (home_cell: n rows of D cell indices of a lattice of `cells` cells), or
/// nullopt when one lies outside that lattice.
template <int D>
std::optional<std::vector<Index<D>>> home_cells_of(const StateGroup& nodes, std::size_t n, const Index<D>& cells);

extern template class Engine<1>;
extern template class Engine<2>;
extern template class Engine<3>;

} // namespace otmpm
