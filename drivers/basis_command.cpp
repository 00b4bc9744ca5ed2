// `otmpm basis`: evaluates one basis family on a node layout at sample points
// along the first axis and writes N and grad N per (point, node) as CSV, so
// shape functions can be plotted (molinos Fig. 4/5) and checked.
#include "commands.hpp"

#include "otmpm/basis/basis.hpp"
#include "otmpm/scene/resources.hpp"
#include "otmpm/scene/scene.hpp"

#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <memory>

namespace otmpm::cli {

namespace {

struct BasisArgs {
  BasisOptions opt;
  int dim = 1;
  double lower = 0.0, upper = 1.0, perturb = 0.0;
  int cells = 10, samples = 201;
  unsigned seed = 1;
  std::string out;
};

double to_double(const std::string& opt, const std::string& v) {
  try {
    std::size_t used = 0;
    const double d = std::stod(v, &used);
    if (used == v.size()) return d;
  } catch (const std::exception&) {
  }
  throw InputError("option " + opt + ": '" + v + "' is not a number");
}

int to_int(const std::string& opt, const std::string& v) {
  const double d = to_double(opt, v);
  // Range first: converting a double outside the int range is undefined.
  const bool in_range = d >= std::numeric_limits<int>::min() && d <= std::numeric_limits<int>::max();
  if (!in_range || d != std::trunc(d)) throw InputError("option " + opt + ": '" + v + "' is not an int");
  return static_cast<int>(d);
}

/// A non-negative --seed (a negative one would wrap to a different seed).
unsigned to_seed(const std::string& opt, const std::string& v) {
  const int seed = to_int(opt, v);
  if (seed < 0) throw InputError("option " + opt + ": '" + v + "' must be >= 0");
  return static_cast<unsigned>(seed);
}

BasisArgs parse(const std::vector<std::string>& args) {
  BasisArgs a;
  for (std::size_t i = 0; i < args.size(); ++i) {
    const std::string& s = args[i];
    if (i + 1 >= args.size()) throw InputError("option " + s + " needs a value");
    const std::string& v = args[++i];
    if (s == "--kind") a.opt.kind = v;
    else if (s == "--dim") a.dim = to_int(s, v);
    else if (s == "--lower") a.lower = to_double(s, v);
    else if (s == "--upper") a.upper = to_double(s, v);
    else if (s == "--cells") a.cells = to_int(s, v);
    else if (s == "--perturb") a.perturb = to_double(s, v);
    else if (s == "--seed") a.seed = to_seed(s, v);
    else if (s == "--gamma-lme") a.opt.gamma_lme = to_double(s, v);
    else if (s == "--tolerance") a.opt.tolerance = to_double(s, v);
    else if (s == "--d-max") a.opt.d_max = to_double(s, v);
    else if (s == "--ppc") a.opt.ugimp_half_width[0] = a.opt.ugimp_half_width[1] = a.opt.ugimp_half_width[2] = 0.5 / to_double(s, v);
    else if (s == "--samples") a.samples = to_int(s, v);
    else if (s == "--out") a.out = v;
    else throw InputError("unknown option '" + s + "'");
  }
  if (a.out.empty()) throw InputError("--out FILE.csv is required");
  if (a.dim < 1 || a.dim > 3) throw InputError("--dim must be 1, 2 or 3");
  if (a.cells < 1 || a.samples < 1 || !(a.lower < a.upper)) throw InputError("need lower < upper, cells >= 1, samples >= 1");
  if (!(a.opt.gamma_lme > 0)) throw InputError("--gamma-lme must be > 0");
  return a;
}

template <int D> int evaluate(BasisArgs a) {
  // The node set must fit as a scene's would (kMaxSceneNodes) and in memory
  // (about 1 kB per node with the basis' neighbour search, generously).
  constexpr double kBytesPerNode = 1000;
  const double node_count = std::pow(a.cells + 1.0, D);
  if (node_count > kMaxSceneNodes || node_count * kBytesPerNode > available_memory())
    throw InputError("--cells " + std::to_string(a.cells) + " gives " + format_number(node_count) + " nodes in " +
                     std::to_string(D) + "D (about " + format_bytes(node_count * kBytesPerNode) + "); at most " +
                     format_number(kMaxSceneNodes) + " nodes and " + format_bytes(available_memory()) +
                     " of memory are available");
  CartesianGrid<D> grid;
  grid.lower.setConstant(a.lower);
  grid.upper.setConstant(a.upper);
  grid.cells.fill(a.cells);
  grid.validate();
  const double h = (a.upper - a.lower) / a.cells;
  // uGIMP half-width: --ppc gives 1/(2 ppc) in cells; default 2 particles per cell.
  for (double& w : a.opt.ugimp_half_width) w = (w > 0 ? w : 0.25) * h;
  NodeSet<D> nodes = a.perturb > 0 ? NodeSet<D>::perturbed(grid, a.perturb, a.seed) : NodeSet<D>::cartesian(grid);
  const auto basis = make_basis<D>(a.opt, std::move(nodes));
  std::ofstream out(a.out);
  if (!out) throw InputError("cannot write '" + a.out + "'");
  out << "point";
  for (int k = 0; k < D; ++k) out << ",x" << k;
  out << ",node";
  for (int k = 0; k < D; ++k) out << ",xI" << k;
  out << ",N";
  for (int k = 0; k < D; ++k) out << ",dN" << k;
  out << "\n";
  out.precision(12);
  Stencil<D> st;
  const double mid = 0.5 * (a.lower + a.upper);
  for (int s = 0; s < a.samples; ++s) {
    PointQuery<D> q;
    q.x.setConstant(mid);
    q.x[0] = a.lower + (a.upper - a.lower) * (a.samples == 1 ? 0.5 : double(s) / (a.samples - 1));
    q.id = s;
    basis->evaluate(q, st);
    for (int e = 0; e < st.size(); ++e) {
      out << s;
      for (int k = 0; k < D; ++k) out << "," << q.x[k];
      out << "," << st.node[e];
      for (int k = 0; k < D; ++k) out << "," << basis->nodes().position(st.node[e])[k];
      out << "," << st.N[e];
      for (int k = 0; k < D; ++k) out << "," << st.dN[e][k];
      out << "\n";
    }
  }
  std::printf("wrote %s (%d points, kind %s)\n", a.out.c_str(), a.samples, a.opt.kind.c_str());
  return 0;
}

} // namespace

int basis_command(const std::vector<std::string>& args) {
  const BasisArgs a = parse(args);
  switch (a.dim) {
  case 1: return evaluate<1>(a);
  case 2: return evaluate<2>(a);
  default: return evaluate<3>(a);
  }
}

} // namespace otmpm::cli
