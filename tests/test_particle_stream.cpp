// Particle files read in blocks of rows (stream_particle_file): the values
// and messages of the whole read at every block size, including files of
// fewer rows than a block, exactly a block and a block plus one; and the
// shape of a file body built one particle at a time (ParticleCells::Builder)
// holding only the particles near where it is asked.
#include "otmpm/geometry/shapes.hpp"
#include "otmpm/io/particle_file.hpp"
#include "particle_file_cases.hpp"
#include "temp_dir.hpp"

#include <doctest/doctest.h>
#include <hdf5.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <functional>
#include <random>
#include <string>
#include <vector>

using namespace otmpm;

namespace {

/// The exact text of a double (17 significant digits: strtod gives it back).
std::string exact(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

/// n 2D rows with velocities and two further fields (`plastic_strain` and
/// `density`, given in that order: the reader lists them in name order).
ParticleFile sample(int n) {
  ParticleFile f{"", 2, {}, {}, {}, {}};
  for (int r = 0; r < n; ++r) {
    f.x.insert(f.x.end(), {0.1 * r + 1.0 / 3.0, std::sqrt(2.0) * r});
    f.volume.push_back(0.01 * (r + 1));
    f.v.insert(f.v.end(), {1.0 * r, -0.7 * r});
    f.fields["plastic_strain"].push_back(0.5 * r / 3.0);
    f.fields["density"].push_back(1000.0 + r);
  }
  return f;
}

void write_csv(const std::string& path, const ParticleFile& f) {
  std::ofstream out(path);
  out << "# a comment line\nx, y, volume, vx, vy, plastic_strain, density\n";
  for (int r = 0; r < f.size(); ++r) {
    const std::size_t i = static_cast<std::size_t>(r);
    out << exact(f.x[2 * i]) << ", " << exact(f.x[2 * i + 1]) << ", " << exact(f.volume[i]) << ", "
        << exact(f.v[2 * i]) << ", " << exact(f.v[2 * i + 1]) << ", " << exact(f.fields.at("plastic_strain")[i]) << ", "
        << exact(f.fields.at("density")[i]) << "\n";
    if (r == 1) out << "\n# a blank line and a comment between rows\n";
  }
}

void write_h5(const std::string& path, const ParticleFile& f) {
  const hsize_t n = static_cast<hsize_t>(f.size());
  test::write_datasets(path, {{"x", n, 2, f.x},
                              {"volume", n, 0, f.volume},
                              {"v", n, 2, f.v},
                              {"plastic_strain", n, 0, f.fields.at("plastic_strain")},
                              {"density", n, 0, f.fields.at("density")}});
}

/// The file streamed in blocks of `chunk` rows, put back together; checks
/// the blocks follow each other and hold at most `chunk` rows.
ParticleFile streamed(const std::string& path, std::size_t chunk, int& blocks) {
  ParticleFile f{path, 2, {}, {}, {}, {}};
  blocks = 0;
  stream_particle_file(
      path, 2,
      [&](const ParticleColumns& c, const ParticleRows& rows) {
        CHECK(c.velocity);
        CHECK(c.fields == std::vector<std::string>{"density", "plastic_strain"});
        CHECK(rows.first == f.size());
        CHECK(rows.size() >= 1);
        CHECK(static_cast<std::size_t>(rows.size()) <= chunk);
        REQUIRE(rows.x.size() == 2 * rows.volume.size());
        REQUIRE(rows.v.size() == 2 * rows.volume.size());
        REQUIRE(rows.fields.size() == 2);
        ++blocks;
        f.x.insert(f.x.end(), rows.x.begin(), rows.x.end());
        f.volume.insert(f.volume.end(), rows.volume.begin(), rows.volume.end());
        f.v.insert(f.v.end(), rows.v.begin(), rows.v.end());
        for (std::size_t i = 0; i < 2; ++i) {
          auto& to = f.fields[c.fields[i]];
          to.insert(to.end(), rows.fields[i].begin(), rows.fields[i].end());
        }
      },
      chunk);
  return f;
}

void check_same(const ParticleFile& a, const ParticleFile& b) {
  CHECK(a.x == b.x); // the same bits
  CHECK(a.volume == b.volume);
  CHECK(a.v == b.v);
  CHECK(a.fields == b.fields);
}

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  return "no error";
}

} // namespace

TEST_CASE("particle files in blocks: the values of the whole read for files shorter than, as long as and one row "
          "longer than a block") {
  test::TempDir tmp("particle_stream");
  constexpr std::size_t kChunk = 4;
  for (const std::string ext : {".csv", ".h5"}) {
    for (const int n : {1, 3, 4, 5, 9}) {
      CAPTURE(ext);
      CAPTURE(n);
      const ParticleFile want = sample(n);
      const std::string path = tmp.file("p" + std::to_string(n) + ext);
      if (ext == ".csv") write_csv(path, want);
      else write_h5(path, want);
      check_same(read_particle_file(path, 2), want);
      for (const std::size_t chunk : {std::size_t{1}, kChunk, kParticleChunk}) {
        CAPTURE(chunk);
        int blocks = 0;
        check_same(streamed(path, chunk, blocks), want);
        CHECK(blocks == static_cast<int>((static_cast<std::size_t>(n) + chunk - 1) / chunk));
      }
    }
  }
}

TEST_CASE("particle files in blocks: the messages of the whole read, whichever block meets the fault") {
  test::TempDir tmp("particle_stream_errors");
  for (const test::FaultyFile& f : test::faulty_files()) {
    CAPTURE(f.name);
    const std::string path = test::write_faulty(tmp.dir.string(), f);
    CHECK(error_of([&] { read_particle_file(path, 2); }) == path + f.message);
    for (const std::size_t chunk : {std::size_t{1}, std::size_t{2}, std::size_t{3}, kParticleChunk}) {
      CAPTURE(chunk);
      int rows = 0;
      CHECK(error_of([&] {
              stream_particle_file(path, 2, [&](const ParticleColumns&, const ParticleRows& r) { rows += r.size(); },
                                   chunk);
            }) == path + f.message);
      CHECK(rows <= 7); // the rows before the bad one at most
    }
  }
}

TEST_CASE("a file body's shape built one particle at a time holds only the particles near where it is asked, "
          "with the answers, bounds and measure of the whole") {
  // Particles on a jittered lattice with volumes that vary (cubes of
  // different sides); a later body is seeded in [0.6, 1.0]^2.
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> jitter(-0.01, 0.01), size(0.5, 1.0);
  AlignedVector<Vec<2>> x;
  std::vector<double> V;
  for (int i = 0; i < 40; ++i)
    for (int j = 0; j < 40; ++j) {
      x.emplace_back(0.025 * i + jitter(rng), 0.025 * j + jitter(rng));
      V.push_back(std::pow(0.025 * size(rng), 2));
    }
  const ParticleCells<2> whole(x, V);
  const Vec<2> lo(0.6, 0.6), hi(1.0, 1.0);
  ParticleCells<2>::Builder builder(
      [&](const Vec<2>& a, const Vec<2>& b) { return (a.array() <= hi.array()).all() && (b.array() >= lo.array()).all(); });
  for (std::size_t p = 0; p < x.size(); ++p) builder.add(x[p], V[p]);
  const std::unique_ptr<ParticleCells<2>> part = builder.finish();
  CHECK(whole.held() == x.size());
  CHECK(part->held() < x.size() / 3);
  CHECK(part->held() > 0);
  Vec<2> wlo, whi, plo, phi;
  whole.bounds(wlo, whi);
  part->bounds(plo, phi);
  CHECK(wlo == plo);
  CHECK(whi == phi);
  CHECK(whole.measure() == part->measure());
  // Probes in the region: a fine lattice and the faces and corners of every cube.
  int inside = 0, probes = 0;
  auto probe = [&](const Vec<2>& q) {
    if ((q.array() < lo.array()).any() || (q.array() > hi.array()).any()) return;
    ++probes;
    const bool in = whole.contains(q);
    inside += in;
    CHECK(part->contains(q) == in);
  };
  for (int i = 0; i <= 200; ++i)
    for (int j = 0; j <= 200; ++j) probe(Vec<2>(0.6 + 0.002 * i, 0.6 + 0.002 * j));
  for (std::size_t p = 0; p < x.size(); ++p) {
    const double h = 0.5 * std::sqrt(V[p]);
    for (const double dx : {-h, 0.0, h})
      for (const double dy : {-h, 0.0, h}) probe(Vec<2>(x[p][0] + dx, x[p][1] + dy));
  }
  CHECK(inside > probes / 4); // the probes meet the shape and its outside
  CHECK(inside < probes);
  // Without a filter the builder gives the constructor's shape.
  ParticleCells<2>::Builder all;
  for (std::size_t p = 0; p < x.size(); ++p) all.add(x[p], V[p]);
  const auto full = all.finish();
  CHECK(full->held() == x.size());
  for (int i = 0; i <= 100; ++i)
    for (int j = 0; j <= 100; ++j) {
      const Vec<2> q(-0.05 + 0.011 * i, -0.05 + 0.011 * j);
      CHECK(full->contains(q) == whole.contains(q));
    }
  CHECK(error_of([] { ParticleCells<2>::Builder().finish(); }) == "particle file: no particles");
}

TEST_CASE("particle files: a CSV column named twice is refused (its values would go to one field twice)") {
  test::TempDir tmp("particle_stream_twice");
  for (const std::string header : {"x, y, volume, a, a", "x, y, x, volume"}) {
    CAPTURE(header);
    const std::string path = tmp.file("p.csv");
    std::ofstream(path) << "# a comment\n" << header << "\n0, 0, 1, 2, 3\n";
    const std::string name = header.find("a, a") != std::string::npos ? "a" : "x";
    CHECK(error_of([&] { read_particle_file(path, 2); }) == path + ":2: column '" + name + "' appears twice");
  }
}

TEST_CASE("particle files in blocks: an HDF5 file whose datasets are each one deflated chunk larger than the "
          "default chunk cache gives the whole read's values") {
  // 150 000 rows: x is one 2.4 MB chunk, more than HDF5's default 1 MiB
  // chunk cache, which the reader enlarges for such a dataset (else every
  // block re-reads and inflates the whole chunk).
  test::TempDir tmp("particle_stream_chunked");
  const std::string path = tmp.file("one_chunk.h5");
  const hsize_t n = 150000;
  std::vector<double> x(2 * n), volume(n);
  for (hsize_t i = 0; i < n; ++i) {
    x[2 * i] = 1e-3 * static_cast<double>(i % 1000) + 1.0 / 3.0;
    x[2 * i + 1] = 1e-3 * static_cast<double>(i / 1000);
    volume[i] = 1e-6 * (1.0 + static_cast<double>(i % 7));
  }
  const hid_t file = H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
  REQUIRE(file >= 0);
  for (const bool positions : {true, false}) {
    const hsize_t dims[2] = {n, 2};
    const int rank = positions ? 2 : 1;
    const hid_t space = H5Screate_simple(rank, dims, nullptr);
    const hid_t create = H5Pcreate(H5P_DATASET_CREATE);
    REQUIRE(H5Pset_chunk(create, rank, dims) >= 0);
    REQUIRE(H5Pset_deflate(create, 1) >= 0);
    const hid_t set = H5Dcreate2(file, positions ? "x" : "volume", H5T_IEEE_F64LE, space, H5P_DEFAULT, create,
                                 H5P_DEFAULT);
    REQUIRE(H5Dwrite(set, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, positions ? x.data() : volume.data()) >= 0);
    H5Dclose(set);
    H5Pclose(create);
    H5Sclose(space);
  }
  H5Fclose(file);
  const ParticleFile whole = read_particle_file(path, 2);
  CHECK(whole.x == x);
  CHECK(whole.volume == volume);
  for (const std::size_t chunk : {std::size_t{1000}, kParticleChunk}) {
    CAPTURE(chunk);
    std::vector<double> got_x, got_volume;
    int blocks = 0;
    stream_particle_file(
        path, 2,
        [&](const ParticleColumns&, const ParticleRows& rows) {
          got_x.insert(got_x.end(), rows.x.begin(), rows.x.end());
          got_volume.insert(got_volume.end(), rows.volume.begin(), rows.volume.end());
          ++blocks;
        },
        chunk);
    CHECK(got_x == x);
    CHECK(got_volume == volume);
    CHECK(blocks == static_cast<int>((n + chunk - 1) / chunk));
  }
}
