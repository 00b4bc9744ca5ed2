#pragma once
// HDF5 helpers shared by the tests that read result files directly, write
// particle files or build HDF5 files of their own in a temporary directory.
#include "otmpm/io/hdf5.hpp"
#include "temp_dir.hpp"

#include <hdf5.h>

#include <stdexcept>
#include <string>
#include <vector>

namespace otmpm::test {

/// The path of every dataset in the open HDF5 file `file`, in name order
/// (groups visited recursively).
inline std::vector<std::string> dataset_names(hid_t file) {
  struct Visit {
    static herr_t call(hid_t, const char* name, const H5O_info_t* info, void* data) {
      if (info->type == H5O_TYPE_DATASET) static_cast<std::vector<std::string>*>(data)->push_back(name);
      return 0;
    }
  };
  std::vector<std::string> names;
  H5Ovisit2(file, H5_INDEX_NAME, H5_ITER_INC, Visit::call, &names, H5O_INFO_BASIC);
  return names;
}

/// One dataset to write: rows x cols doubles (cols = 0: a rank-1 dataset of rows values).
struct Dataset {
  std::string name;
  hsize_t rows = 0, cols = 0;
  std::vector<double> values;
};

/// Writes the datasets (64-bit floats) as a new HDF5 file at `path`.
inline void write_datasets(const std::string& path, const std::vector<Dataset>& sets) {
  const hid_t f = H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
  for (const Dataset& d : sets) {
    const hsize_t dims[2] = {d.rows, d.cols};
    const hid_t space = H5Screate_simple(d.cols == 0 ? 1 : 2, dims, nullptr);
    const hid_t set = H5Dcreate2(f, d.name.c_str(), H5T_IEEE_F64LE, space, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    if (!d.values.empty()) H5Dwrite(set, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, d.values.data());
    H5Dclose(set);
    H5Sclose(space);
  }
  H5Fclose(f);
}

/// A new, empty HDF5 file in a test's temporary directory, open for writing.
struct NewH5File {
  std::string path; ///< where it is (inside the TempDir)
  h5::Handle file;  ///< the open file, closed when this goes out of scope
};

/// Creates the empty HDF5 file `name` in `dir` (replacing any file of that
/// name), with HDF5's printing of its error stack silenced as the library
/// does. Throws std::runtime_error naming the path when HDF5 cannot create it.
inline NewH5File new_h5_file(const TempDir& dir, const std::string& name) {
  NewH5File created{dir.file(name), {}};
  h5::silence();
  created.file = h5::Handle(H5Fcreate(created.path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT), H5Fclose);
  if (!created.file.valid()) throw std::runtime_error(created.path + ": HDF5 cannot create the file");
  return created;
}

} // namespace otmpm::test
