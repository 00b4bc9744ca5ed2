// `otmpm study`: a 2 x 2 sweep (two integrators x two meshes of the Dyka bar)
// writes one CSV row per run with the expected parameters and errors, and a
// rerun resumes: rows already present are not run again. A [stability] study
// classifies a stable and a blown-up cfl and draws the stability map. The
// file-handling cases of the study (killed studies, colliding names, bad paths
// and overrides, cut-off rows) are in test_study_files.cpp.
#include "study_support.hpp"

#include <doctest/doctest.h>

#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>
#include <string>
#include <vector>

namespace fs = std::filesystem;
using namespace otmpm::test;

TEST_CASE("study: a 2x2 sweep writes one CSV row per run with parameters, status and errors") {
  const fs::path dir = make_study_dir("rows");
  std::string out;
  REQUIRE(run_study(dir, out) == 0);
  const auto rows = read_csv(dir / "study.csv");
  REQUIRE(rows.size() == 5); // header + 2 integrators x 2 meshes
  const auto& h = rows[0];
  std::set<std::string> seen;
  for (std::size_t r = 1; r < rows.size(); ++r) {
    const auto& row = rows[r];
    REQUIRE(row.size() == h.size());
    seen.insert(row[column(h, "variant")] + "@" + row[column(h, "mesh")]);
    CHECK(row[column(h, "status")] == "ok");
    CHECK(row[column(h, "simulation.integrator")] == row[column(h, "variant")]);
    // The Dyka velocity error after 2e-5 s is of the order of the 5 m/s jump
    // smeared over a few cells: positive, finite and well below 5 m/s.
    const double e = std::stod(row[column(h, "rms_velocity_error")]);
    CHECK(e > 0.0);
    CHECK(e < 5.0);
    CHECK(std::stod(row[column(h, "wall_seconds")]) > 0.0);
    CHECK(std::stod(row[column(h, "steps")]) > 0.0);
  }
  CHECK(seen == std::set<std::string>{"fe@n13", "npc@n13", "fe@n20", "npc@n20"});
  CHECK(fs::exists(dir / "study_work_precision.png"));
  CHECK(fs::exists(dir / "study_convergence.svg"));
  fs::remove_all(dir);
}

TEST_CASE("study: a rerun skips the runs already in the CSV and completes a truncated one") {
  const fs::path dir = make_study_dir("resume");
  std::string out;
  REQUIRE(run_study(dir, out) == 0);
  REQUIRE(run_study(dir, out) == 0);
  // a study with nothing to run says so, and why
  CHECK(out.find("nothing to run: all 4 runs are already in") != std::string::npos);
  CHECK(read_csv(dir / "study.csv").size() == 5);
  // Drop the last row, as if the study had been interrupted: only that run is redone.
  auto rows = read_csv(dir / "study.csv");
  std::ifstream in(dir / "study.csv");
  std::string text, line;
  for (std::size_t i = 0; i + 1 < rows.size() && std::getline(in, line); ++i) text += line + "\n";
  in.close();
  std::ofstream(dir / "study.csv") << text;
  REQUIRE(run_study(dir, out) == 0);
  CHECK(out.find("1 to do") != std::string::npos);
  CHECK(read_csv(dir / "study.csv").size() == 5);
  fs::remove_all(dir);
}

TEST_CASE("study: a scene without an exact solution gets no empty error plots, and the study says so") {
  const fs::path dir = study_dir("no_errors", "");
  std::ofstream(dir / "study.toml", std::ios::trunc)
      << "scene = \"" OTMPM_SOURCE_DIR "/examples/column_collapse_mu_i.toml\"\ncsv = \"study.csv\"\n"
      << "set = [\"simulation.t_end=0.002\", \"output.every=0.001\"]\n"
      << "[[mesh]]\nname = \"L0-5\"\nh = 0.04\nset = [\"grid.h=0.04\"]\n";
  std::string out;
  REQUIRE(run_study(dir, out) == 0);
  INFO(out);
  const auto rows = read_csv(dir / "study.csv");
  REQUIRE(rows.size() == 2);
  CHECK(rows[1][column(rows[0], "status")] == "ok");
  CHECK(rows[1][column(rows[0], "rms_velocity_error")].empty());
  CHECK(out.find("no run has a value in column rms_velocity_error") != std::string::npos);
  CHECK(!fs::exists(dir / "study_work_precision.png"));
  CHECK(!fs::exists(dir / "study_convergence.png"));
  fs::remove_all(dir);
}

/// The (variant, mesh) pairs of a study CSV's rows, as "variant@mesh".
std::set<std::string> csv_runs(const fs::path& csv) {
  const auto rows = read_csv(csv);
  std::set<std::string> runs;
  for (std::size_t r = 1; r < rows.size(); ++r)
    runs.insert(rows[r][column(rows[0], "variant")] + "@" + rows[r][column(rows[0], "mesh")]);
  return runs;
}

TEST_CASE("study: --variant and --mesh run only the runs they name, the next study the others") {
  const fs::path dir = make_study_dir("parts");
  std::string out;
  REQUIRE(run_study(dir, out, " --mesh n20") == 0);
  INFO(out);
  CHECK(out.find("4 runs, 2 chosen by --variant/--mesh, 0 of them already in") != std::string::npos);
  CHECK(csv_runs(dir / "study.csv") == std::set<std::string>{"fe@n20", "npc@n20"});
  CHECK(!fs::exists(dir / "study_results" / "fe_n13.h5"));
  REQUIRE(run_study(dir, out, " --variant npc --mesh n13 --mesh n20") == 0);
  CHECK(out.find("2 chosen by --variant/--mesh, 1 of them already in") != std::string::npos);
  CHECK(csv_runs(dir / "study.csv") == std::set<std::string>{"fe@n20", "npc@n20", "npc@n13"});
  REQUIRE(run_study(dir, out, " --variant npc") == 0);
  CHECK(out.find("nothing to run: the 2 runs chosen by --variant/--mesh are already in") !=
        std::string::npos);
  REQUIRE(run_study(dir, out) == 0);
  CHECK(out.find("4 runs, 3 already in") != std::string::npos);
  CHECK(csv_runs(dir / "study.csv") == std::set<std::string>{"fe@n13", "fe@n20", "npc@n13", "npc@n20"});
  fs::remove_all(dir);
}

TEST_CASE(
    "study: a --variant or --mesh name the study does not have is refused with exit 2, naming its names") {
  const fs::path dir = make_study_dir("parts_bad");
  std::string out;
  CHECK(run_study(dir, out, " --mesh n30") == 2);
  CHECK(out.find("study.toml: --mesh 'n30' is none of its meshes: n13, n20") != std::string::npos);
  CHECK(run_study(dir, out, " --variant fe --variant FE") == 2);
  CHECK(out.find("--variant 'FE' is none of its variants: fe, npc") != std::string::npos);
  CHECK(!fs::exists(dir / "study.csv"));
  CHECK(!fs::exists(dir / "study_results"));
  fs::remove_all(dir);
}

TEST_CASE("study: a CSV written before the energy columns is extended in place and resumed") {
  const fs::path dir = make_study_dir("upgrade");
  std::string out;
  REQUIRE(run_study(dir, out) == 0);
  // Rewrite the CSV as an older otmpm wrote it: without the two energy
  // columns and the two pore-pressure columns after them, and without its last row.
  const auto rows = read_csv(dir / "study.csv");
  const std::size_t ratio = column(rows[0], "max_energy_ratio");
  REQUIRE(ratio + 4 == rows[0].size());
  CHECK(rows[0][ratio + 2] == "rms_pore_pressure_error");
  std::string text;
  for (std::size_t r = 0; r + 1 < rows.size(); ++r) {
    for (std::size_t c = 0; c < ratio; ++c) text += (c ? "," : "") + rows[r][c];
    text += "\n";
  }
  std::ofstream(dir / "study.csv") << text;
  REQUIRE(run_study(dir, out) == 0);
  CHECK(out.find("added the columns") != std::string::npos);
  CHECK(out.find("1 to do") != std::string::npos);
  const auto now = read_csv(dir / "study.csv");
  REQUIRE(now.size() == 5);
  CHECK(now[0] == rows[0]);
  CHECK(now[1].size() == rows[0].size()); // padded with empty cells
  CHECK(now[1][ratio].empty());
  CHECK(std::stod(now[4][ratio]) > 0.0); // the rerun row is measured
  fs::remove_all(dir);
}

TEST_CASE("study: a [stability] sweep marks a blown-up cfl unstable, the stable one stable, and draws the map") {
  // The Dyka bar at h = L/13 with the linear basis and forward Euler: cfl 0.5
  // is below the limit measured for this combination at L/133 and L/401
  // (0.7, docs/stability.md); cfl 3 is far past it (measured: the runaway
  // monitor stops the run at step 2).
  const fs::path dir = study_dir("stability", std::string("jobs = 1\n"
                                                          "set = [\"output.fields=[]\", \"basis.kind=linear\", "
                                                          "\"simulation.integrator=fe\"]\n"
                                                          "[stability]\nband = 0.05\n"
                                                          "[sweep]\n\"simulation.cfl\" = [0.5, 3.0]\n") +
                                                  kMeshN13);
  std::string out;
  REQUIRE(run_study(dir, out) == 0);
  const auto rows = read_csv(dir / "study.csv");
  REQUIRE(rows.size() == 3);
  const auto& h = rows[0];
  CHECK(h[h.size() - 3] == "stability"); // then the pore-pressure errors (empty for a dry scene)
  CHECK(h.back() == "max_pore_pressure_error");
  for (std::size_t r = 1; r < rows.size(); ++r) {
    const auto& row = rows[r];
    const std::string cfl = row[column(h, "simulation.cfl")];
    INFO("cfl " << cfl << ": " << row[column(h, "status")]);
    const double ratio = std::stod(row[column(h, "max_energy_ratio")]);
    if (cfl == "0.5") {
      CHECK(row[column(h, "stable")] == "1");
      CHECK(row[column(h, "stability")] == "stable");
      CHECK(ratio <= 1.05);
      CHECK(ratio >= 1.0);
    } else {
      CHECK(cfl == "3");
      CHECK(row[column(h, "stable")] == "0");
      CHECK(row[column(h, "stability")] == "blown_up");
      CHECK(row[column(h, "exit_code")] == "1");
      CHECK(ratio > 10.0); // the runaway monitor stops at 10 x the reference
    }
  }
  // scripts/plot_stability.py ran: the map and the markdown table.
  CHECK(fs::exists(dir / "study_map.png"));
  CHECK(fs::exists(dir / "study_map.svg"));
  CHECK(out.find("| base | 0.5 | 3 (blown_up) |") != std::string::npos);
  // scripts/plot_energy_histories.py reads the /energy series of both result files.
  std::string printed;
  CHECK(run_command("/usr/bin/python3 '" OTMPM_SOURCE_DIR "/scripts/plot_energy_histories.py' 'cfl 0.5=" +
                        (dir / "study_results" / "0.5_n13.h5").string() + "' 'cfl 3=" +
                        (dir / "study_results" / "3_n13.h5").string() + "' --out '" + (dir / "energy.png").string() +
                        "'",
                    printed) == 0);
  INFO(printed);
  CHECK(fs::exists(dir / "energy.png"));
  CHECK(printed.find("cfl 0.5: ") != std::string::npos);
  CHECK(printed.find("status unstable") != std::string::npos);
  fs::remove_all(dir);
}

TEST_CASE("study: a [stability] table without a positive band or with an unswept key is refused") {
  for (const auto& [table, what] : std::vector<std::pair<std::string, std::string>>{
           {"[stability]\nband = 0.0\n", "stability.band"},
           {"[stability]\n", "stability.band"},
           {"[stability]\nband = 0.05\nkey = \"simulation.gamma\"\n", "'simulation.gamma' is not swept"}}) {
    const fs::path dir = study_dir("bad_stability", table + "[sweep]\n\"simulation.cfl\" = [0.5]\n" + kMeshN13);
    std::string out;
    const std::string& study_table = table; // INFO's lambda cannot capture a structured binding (clang, C++20)
    INFO(study_table);
    CHECK(run_study(dir, out) == 2);
    CHECK(out.find(what) != std::string::npos);
    CHECK(!fs::exists(dir / "study.csv")); // refused before any run
    fs::remove_all(dir);
  }
}

TEST_CASE("study: a malformed study file is refused with exit status 2 and the line") {
  const fs::path dir = make_study_dir("bad");
  std::stringstream text;
  text << "colour = \"red\"\n" << std::ifstream(dir / "study.toml").rdbuf();
  std::ofstream(dir / "study.toml") << text.str();
  std::string out;
  CHECK(run_study(dir, out) == 2);
  CHECK(out.find("study.toml:1:") != std::string::npos);
  CHECK(out.find("colour") != std::string::npos);
  fs::remove_all(dir);
}

TEST_CASE("study: a refused run whose result file is an earlier run's records the refusal, not that file") {
  // One variant "v"; the second study gives it a set the run refuses (the
  // study checks variants' sets only when their run starts). The earlier
  // run finished (status ok) or blew up (cfl = 20: unstable).
  const auto body = [](const std::string& sets) {
    return "set = [\"output.every=1e-5\", \"simulation.t_end=2e-5\"]\n[[variant]]\nname = \"v\"\nset = [" + sets +
           "]\n" + std::string(kMeshN13);
  };
  for (const std::string& first : {std::string(), std::string("\"simulation.cfl=20\"")}) {
    INFO("first run's sets: " << first);
    const fs::path dir = study_dir("stale", body(first));
    std::string out;
    REQUIRE(run_study(dir, out) == 0);
    const auto earlier = read_csv(dir / "study.csv");
    REQUIRE(earlier.size() == 2);
    REQUIRE(earlier[1][column(earlier[0], "status")].rfind(first.empty() ? "ok" : "unstable", 0) == 0);
    // The same run again, now refused before it writes (cfl < 0): its
    // result file is still the earlier run's.
    fs::remove(dir / "study.csv");
    std::ofstream(dir / "study.toml") << study_head() << body("\"simulation.cfl=-1\"");
    run_study(dir, out);
    INFO(out);
    const auto rows = read_csv(dir / "study.csv");
    REQUIRE(rows.size() == 2);
    const auto& h = rows[0];
    CHECK(rows[1][column(h, "status")].rfind("input error: ", 0) == 0);
    CHECK(rows[1][column(h, "exit_code")] == "2");
    // Nothing of the earlier run's file: no steps, wall time, errors or energies.
    for (const char* c : {"steps", "wall_seconds", "particles", "rms_velocity_error", "max_energy_ratio"}) {
      INFO("column " << c << " = " << rows[1][column(h, c)]);
      CHECK((rows[1][column(h, c)].empty() || rows[1][column(h, c)] == "nan"));
    }
    fs::remove_all(dir);
  }
}

TEST_CASE("study: a saturated scene's rows carry its pore-pressure errors, a CSV without those columns is extended") {
  // examples/terzaghi.toml at h = H/16 and H/32 to T_v = 0.05
  const fs::path dir = study_dir("pore", "jobs = 1\nerror = \"max_pore_pressure_error\"\n"
                                         "set = [\"simulation.t_end=0.0501\", \"output.every=0\", \"output.fields=[]\"]\n"
                                         "[[mesh]]\nh = 0.0625\nset = [\"grid.cells=[16]\"]\n"
                                         "[[mesh]]\nh = 0.03125\nset = [\"grid.cells=[32]\"]\n");
  {
    std::string toml;
    std::ifstream in(dir / "study.toml");
    std::getline(in, toml, '\0');
    toml.replace(toml.find("dyka.toml"), 9, "terzaghi.toml");
    std::ofstream(dir / "study.toml") << toml;
  }
  std::string out;
  REQUIRE(run_study(dir, out) == 0);
  const auto rows = read_csv(dir / "study.csv");
  REQUIRE(rows.size() == 3);
  const auto& h = rows[0];
  const double coarse = std::stod(rows[1][column(h, "max_pore_pressure_error")]);
  const double fine = std::stod(rows[2][column(h, "max_pore_pressure_error")]);
  CHECK(std::stod(rows[1][column(h, "rms_pore_pressure_error")]) < coarse);
  CHECK(fine < 0.6 * coarse); // first order in h (docs/benchmarks.md)
  // The CSV as the version before the pore-pressure columns wrote it, without its last row.
  const std::size_t pore = column(h, "rms_pore_pressure_error");
  std::string text;
  for (std::size_t r = 0; r + 1 < rows.size(); ++r) {
    for (std::size_t c = 0; c < pore; ++c) text += (c ? "," : "") + rows[r][c];
    text += "\n";
  }
  std::ofstream(dir / "study.csv") << text;
  REQUIRE(run_study(dir, out) == 0);
  CHECK(out.find("added the columns") != std::string::npos);
  const auto now = read_csv(dir / "study.csv");
  REQUIRE(now.size() == 3);
  CHECK(now[0] == h);
  CHECK(now[1][pore].empty()); // the old row, padded
  CHECK(std::stod(now[2][column(h, "max_pore_pressure_error")]) == doctest::Approx(fine));
  fs::remove_all(dir);
}
