// bench_particle_block: writes a large file body for the set-up memory of
// distributed runs (docs/performance-log-2026.md, "Distributed runs", "Particle files
// at set-up"):
//
//   build/bench/bench_particle_block N DIR
//
// DIR/block.h5: a 2D block [0, 2]^2 of N x N particles (N even) (spacing 2 / N,
// volume (2 / N)^2) as an HDF5 particle file (datasets x, N^2 x 2, and
// volume); DIR/block.toml: a scene with that file body, 2 x 2 particles per
// cell of a linear basis, two steps of `fe` and no output but the last
// frame. Prints the particle count.
#include "otmpm/openmp_wait.hpp"
#include <hdf5.h>

#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <string>
#include <vector>

namespace {

/// Writes a rank-1 (cols = 0) or rank-2 dataset of doubles.
void write(hid_t file, const char* name, hsize_t rows, hsize_t cols, const std::vector<double>& values) {
  const hsize_t dims[2] = {rows, cols};
  const hid_t space = H5Screate_simple(cols == 0 ? 1 : 2, dims, nullptr);
  const hid_t set = H5Dcreate2(file, name, H5T_IEEE_F64LE, space, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
  H5Dwrite(set, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, values.data());
  H5Dclose(set);
  H5Sclose(space);
}

} // namespace

int main(int argc, char** argv) {
  otmpm::default_openmp_wait(argv); // as the otmpm command waits (openmp_wait.hpp)
  if (argc != 3 || std::atoi(argv[1]) < 2 || std::atoi(argv[1]) % 2 != 0) {
    std::fprintf(stderr, "usage: bench_particle_block N DIR (N even)\n");
    return 2;
  }
  const int n = std::atoi(argv[1]);
  const std::string dir = argv[2];
  const double d = 2.0 / n;
  const hsize_t rows = static_cast<hsize_t>(n) * static_cast<hsize_t>(n);
  std::vector<double> x;
  x.reserve(2 * rows);
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) x.push_back((i + 0.5) * d), x.push_back((j + 0.5) * d);
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr); // the message below instead of the error stack
  const hid_t file = H5Fcreate((dir + "/block.h5").c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
  if (file < 0) {
    std::fprintf(stderr, "bench_particle_block: cannot write %s/block.h5\n", dir.c_str());
    return 1;
  }
  write(file, "x", rows, 2, x);
  write(file, "volume", rows, 0, std::vector<double>(rows, d * d));
  H5Fclose(file);
  const double h = 2.0 * d, pad = 4 * h; // 2 x 2 particles per cell, 4 cells around
  std::ofstream toml(dir + "/block.toml");
  toml.precision(17);
  toml << "[simulation]\ndimension = 2\nmode = \"mpm\"\nintegrator = \"fe\"\nt_end = 2.0e-6\ndt = 1.0e-6\n"
      << "[basis]\nkind = \"linear\"\n[grid]\nlower = [" << -pad << ", " << -pad << "]\nupper = [" << 2 + pad << ", "
      << 2 + pad << "]\ncells = [" << n / 2 + 8 << ", " << n / 2 + 8 << "]\n"
      << "[[material]]\nname = \"m\"\nmodel = \"linear_elastic\"\ndensity = 1000.0\nyoung = 1.0e6\npoisson = 0.3\n"
      << "[[body]]\nname = \"block\"\nmaterial = \"m\"\nshape = \"file\"\nfile = \"block.h5\"\nvelocity = [0.1, 0.0]\n"
      << "[output]\nevery = 0\n";
  std::printf("%llu particles: %s/block.h5, %s/block.toml\n", static_cast<unsigned long long>(rows), dir.c_str(),
              dir.c_str());
  return 0;
}
