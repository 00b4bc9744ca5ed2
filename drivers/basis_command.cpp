// `otmpm basis`: evaluates one basis family on a node layout at sample points
// along the first axis and writes N and grad N per (point, node) as CSV, so
// shape functions can be plotted (molinos Fig. 4/5) and checked.
#include "cli.hpp"

#include "otmpm/basis/basis.hpp"
#include "otmpm/basis/kinds.hpp"
#include "otmpm/io/output_files.hpp"
#include "otmpm/scene/resources.hpp"
#include "otmpm/scene/scene.hpp"

#include <algorithm>
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
  int seed = 1;
  double ppc = 0.0; ///< uGIMP particles per cell (0: the default 2)
  int threads = 0;
  std::string out;
};

/// Adds an integer option that also accepts a whole number written as a
/// float (--cells 1e3), as the scene file does not but shell scripts often do.
CLI::Option* add_int_option(CLI::App& sub, const std::string& name, int& target, const std::string& help) {
  return sub
      .add_option_function<double>(
          name,
          [&target, name](const double& v) {
            // Range first: converting a double outside the int range is undefined.
            if (!(v >= std::numeric_limits<int>::min() && v <= std::numeric_limits<int>::max()) || v != std::trunc(v))
              throw CLI::ValidationError(name, "'" + std::to_string(v) + "' is not an int");
            target = static_cast<int>(v);
          },
          help)
      ->type_name("INT")
      ->default_str(std::to_string(target));
}

/// The command-line flag of a basis parameter: "--gamma-lme" for gamma_lme.
std::string flag_of(std::string_view key) {
  std::string flag = "--" + std::string(key);
  std::replace(flag.begin(), flag.end(), '_', '-');
  return flag;
}

void check(const BasisArgs& a) {
  if (const std::string kind = special_file(a.out); !kind.empty())
    throw InputError("--out " + a.out + " is " + kind + ", not a CSV file");
  if (!(a.lower < a.upper)) throw InputError("need --lower < --upper");
  for (const auto& [key, value] : a.opt.values) // every family's, as the scene reader checks them
    if (const std::string why = find_basis_parameter(key)->check(value); !why.empty())
      throw InputError(flag_of(key) + ": " + why);
  check_node_count(std::pow(a.cells + 1.0, a.dim),
                   "--cells " + std::to_string(a.cells) + " in " + std::to_string(a.dim) + "D");
}

template <int D> int evaluate(BasisArgs a) {
  CartesianGrid<D> grid;
  grid.lower.setConstant(a.lower);
  grid.upper.setConstant(a.upper);
  grid.cells.fill(a.cells);
  grid.validate();
  const double h = (a.upper - a.lower) / a.cells;
  // uGIMP half-width: --ppc gives 1/(2 ppc) in cells; default 2 particles per cell.
  for (double& w : a.opt.particle_half_width) w = (a.ppc > 0 ? 0.5 / a.ppc : 0.25) * h;
  NodeSet<D> nodes = a.perturb != 0.0 ? NodeSet<D>::perturbed(grid, a.perturb, static_cast<unsigned>(a.seed))
                                   : NodeSet<D>::cartesian(grid);
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

int basis_command(const BasisArgs& a) {
  check(a);
  set_threads(a.threads);
  switch (a.dim) {
  case 1: return evaluate<1>(a);
  case 2: return evaluate<2>(a);
  default: return evaluate<3>(a);
  }
}

} // namespace

Command add_basis_command(CLI::App& app) {
  auto a = std::make_shared<BasisArgs>();
  CLI::App* sub = app.add_subcommand(
      "basis", "Evaluate a basis family on a Cartesian node layout and write N and grad N at sample points as CSV");
  std::vector<std::string> kinds;
  for (const BasisKind& k : basis_kinds()) kinds.emplace_back(k.name);
  sub->add_option("--kind", a->opt.kind, "Basis family")->check(CLI::IsMember(kinds))->capture_default_str();
  add_int_option(*sub, "--dim", a->dim, "Dimension; in 2D/3D the samples run along x at the centre of the other axes")
      ->check(CLI::Range(1, 3));
  sub->add_option("--lower", a->lower, "Lower end of the box, the same on every axis")->capture_default_str();
  sub->add_option("--upper", a->upper, "Upper end of the box")->capture_default_str();
  add_int_option(*sub, "--cells", a->cells, "Cells per axis")->check(CLI::PositiveNumber);
  sub->add_option("--perturb", a->perturb, "Move interior nodes randomly by up to F h (a fraction of h)")
      ->type_name("F")
      ->capture_default_str();
  add_int_option(*sub, "--seed", a->seed, "Random seed of --perturb")->check(CLI::NonNegativeNumber);
  for (const ParameterSpec* p : basis_parameters()) // the families' parameters, as [basis] in a scene
    sub->add_option_function<double>(
           flag_of(p->key), [a, key = std::string(p->key)](const double& v) { a->opt.values[key] = v; },
           std::string(p->description))
        ->type_name(p->integer ? "INT" : "X")
        ->default_str(format_number(p->fallback.value_or(0.0)));
  sub->add_option("--ppc", a->ppc, "uGIMP particles per cell (half-width h / (2 P)); default 2")
      ->type_name("P")
      ->check(CLI::PositiveNumber);
  add_int_option(*sub, "--samples", a->samples, "Sample points on [lower, upper], end points included")
      ->check(CLI::PositiveNumber);
  sub->add_option("--out", a->out, "Output file")->type_name("FILE.csv")->required();
  add_threads_option(*sub, a->threads);
  return [a] { return basis_command(*a); };
}

} // namespace otmpm::cli
