#pragma once
// HDF5 helpers shared by the tests that read result files directly.
#include <hdf5.h>

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

} // namespace otmpm::test
