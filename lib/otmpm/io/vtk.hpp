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
///
/// A distributed run writes each frame in pieces, ParaView's convention for
/// parallel data: every rank its rows of the frame (in global order, the
/// rows [N r/P, N (r+1)/P) of the result file) as frame_NNNNNN_RRRR.vtp,
/// and the root frame_NNNNNN.pvtp (.pvtu), which names the pieces and is
/// what the .pvd collection lists: no rank holds the whole frame.
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
  /// Float64); `io`: the ranks of a distributed run, each writing its piece
  /// (every rank makes every call; the root writes the collection). Creates
  /// `dir` if needed (the root).
  VtkSeriesWriter(std::string pvd, std::string dir, std::string extension, int dimension, std::string run_id,
                  std::string result_name, bool single = false, ParallelIo io = {});

  /// Writes DIR/frame_NNNNNN.EXT (NNNNNN = `index`) from the fields of one
  /// frame; `fields` must contain "x" (rows x dimension). A distributed run:
  /// this rank's piece from its rows (`fields`), and on the root the file
  /// naming the pieces. OutputError when a file cannot be written. The
  /// collection names the frame after publish().
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
  ParallelIo io_;
  /// The content of a VTK file of the rows of `fields`.
  std::string frame_text(double time, const std::vector<FieldView>& fields) const;
  /// The content of the file that names the `io_.size` pieces of a frame.
  std::string pieces_text(int index, const std::vector<FieldView>& fields) const;
  /// Writes `text` into DIR/name (OutputError when it cannot).
  void write_file(const std::string& name, const std::string& text) const;
  std::vector<std::pair<double, std::string>> frames_; ///< time, file name relative to the .pvd
  std::size_t published_ = 0;
};

} // namespace otmpm
