#pragma once
/// \file vtk.hpp
/// VTK XML output of the particle frames, for users of ParaView and of the
/// peer codes' tool chains (`output.format = ["hdf5", "vtp"]` or "vtu"): one
/// file per frame - PolyData (.vtp) with one vertex per particle, or an
/// UnstructuredGrid (.vtu) of VTK_VERTEX cells - and a .pvd collection that
/// lists them with their times. The HDF5 result file stays the source of
/// truth; the VTK files hold the same point data.
///
/// Each frame file holds the points (x padded with zeros to 3 components),
/// the vertex cells, every other field with one row per particle as point
/// data (as many components as in the HDF5 file: stress in 2D has 4; a field
/// with named components, FieldView::components, names them with the
/// DataArray attributes ComponentName0, ...), and the
/// time as field data `TimeValue`. Arrays are stored as raw appended binary
/// (header_type UInt64, the machine's byte order), so every bit of the
/// doubles is kept. Every file carries the run id and the result file's
/// name as attributes of its VTKFile element (`otmpm_run_id="..."
/// otmpm_result="..."`, see output_files.hpp).
#include "otmpm/io/results.hpp"

#include <string>
#include <utility>
#include <vector>

namespace otmpm {

/// Writes the VTK frame files of one run into `dir` and the collection `pvd`.
class VtkSeriesWriter {
public:
  /// `extension`: "vtp" or "vtu"; `dimension`: 1, 2 or 3; `result_name`: the
  /// HDF5 result file's name, recorded with the run id; `single`: points and
  /// point data as Float32 (output.precision = "single"; the time stays
  /// Float64). Creates `dir` if needed.
  VtkSeriesWriter(std::string pvd, std::string dir, std::string extension, int dimension, std::string run_id,
                  std::string result_name, bool single = false);

  /// Writes DIR/frame_NNNNNN.EXT (NNNNNN = `index`) from the fields of one
  /// frame; `fields` must contain "x" (rows x dimension). OutputError when
  /// the file cannot be written. The collection names it after publish().
  void write_frame(int index, double time, const std::vector<FieldView>& fields);
  /// Rewrites the .pvd collection (atomically: a temporary renamed into
  /// place) so that it lists every frame written. OutputError on failure.
  void publish();
  /// Frames written.
  std::size_t frames() const { return frames_.size(); }

private:
  std::string pvd_, dir_, extension_, run_id_, result_name_;
  int dimension_;
  bool single_;
  std::vector<std::pair<double, std::string>> frames_; ///< time, file name relative to the .pvd
  std::size_t published_ = 0;
};

} // namespace otmpm
