#pragma once
/// \file results.hpp
/// The HDF5 result file (docs/user-guide.md, "Result file"): root attributes, /frames/NNNNNN/
/// groups of particle datasets, `/probes/NAME/` histories, root-level time
/// series (/energy/), and an .xdmf sidecar that ParaView opens (optionally
/// also VTK files, vtk.hpp). Every frame is flushed to disk before the
/// sidecar names it, so a run killed at any moment leaves a readable file
/// (the sidecar may lag the .h5 file by at most 0.25 s of wall time). Space
/// for every write is reserved first, so a full disk or a file size limit
/// ends the output with an OutputError and a valid, shorter file (a
/// compressed frame reserves its uncompressed size and the filters' worst case).
#include "otmpm/io/parallel_io.hpp"
#include "otmpm/text.hpp"

#include <functional>
#include <memory>
#include <set>
#include <string>
#include <vector>

namespace otmpm {

/// One particle field of a frame: `rows` particles by `cols` components,
/// row-major contiguous doubles (e.g. x: cols = D; stress: cols = D*D).
struct FieldView {
  std::string name;
  int rows = 0;
  int cols = 0;
  const double* data = nullptr;
  /// A parallel file: the frame has `total_rows` rows, of which this view
  /// holds rows [first_row, first_row + rows). -1: the view is the whole
  /// frame (in a parallel file, written by the root rank).
  long long total_rows = -1;
  long long first_row = 0;
  /// The names of the columns, separated by single spaces, when they are not
  /// the plain layout (a symmetric tensor stored by its independent
  /// components: "xx xy xz yy yz zz"); written as the dataset's string
  /// attribute `components`. "" : no attribute.
  std::string components{};
};

/// Options of a ResultWriter.
struct ResultOptions {
  /// Root attribute `run_id`, also recorded in the sidecars and checkpoints
  /// (output_files.hpp); "" draws a new one.
  std::string run_id;
  /// "" (HDF5 and XDMF only), "vtp" or "vtu": also one VTK file per frame and
  /// a .pvd collection (vtk.hpp), named as in output_files().
  std::string vtk_format;
  /// Store the frames' particle datasets as 32-bit IEEE floats (each value
  /// rounded to nearest; also Float32 in the VTK files) instead of doubles.
  /// Times, attributes, histories and series stay double.
  bool single_precision = false;
  /// Deflate (gzip) level 0..9 of the frames' particle datasets and the
  /// sidecar's connectivity (output.compression): 0 stores them contiguous;
  /// above 0 each is chunked along its rows (chunks of at most 1 MiB
  /// uncompressed, all columns; h5::chunk_rows) with HDF5's shuffle and
  /// deflate filters. Readers decompress transparently; the values are the same.
  int compression = 0;
};

/// Writes one result file (with a ParallelIo: all ranks of a distributed run
/// together, with the parallel HDF5 - every rank makes every call, with the
/// same arguments except the rows of a frame; the root rank writes the
/// history samples and the XDMF sidecar). Creating it writes the root attributes
/// otmpm_version, run_id, scene and status = "running"; finish() sets the final
/// status and the summary attributes. The destructor closes the file
/// (status stays whatever was last set). An existing file at `path` is
/// replaced (removed, then created anew: a reader holding it open keeps the
/// old one); whether it may be replaced is decided before (claim_outputs in
/// output_files.hpp, which run_scene applies).
///
/// Argument checks: an empty path, a path with an extension reserved for the
/// files beside it (.xdmf, ...), a sidecar that resolves to the result file
/// or a file that cannot be created is an
/// InputError; a dimension outside 1..3, an invalid (invalid_name_reason) or duplicate name, a field
/// shape that does not describe its data (rows < 0, cols < 1, null data, "x"
/// without one column per dimension) or probe fields that change between
/// samples is std::invalid_argument; NaN or Inf in a frame or probe sample is
/// an InstabilityError (nothing of that frame or sample is written). An
/// output that does not fit (no space, file size limit) or a write HDF5
/// reports as failed is an OutputError; after a failed HDF5 write the file
/// is not touched again (writable() is false).
class ResultWriter {
public:
  ResultWriter(const std::string& path, const std::string& scene_text, int dimension,
               const ResultOptions& options = {}, ParallelIo parallel = {});
  ~ResultWriter();
  ResultWriter(const ResultWriter&) = delete;
  ResultWriter& operator=(const ResultWriter&) = delete;

  /// Appends /frames/NNNNNN with attribute time and the given fields; the
  /// field named "x" gives the point coordinates in the XDMF sidecar (with
  /// VTK output, also the VTK frame: in a parallel file each rank's piece of
  /// its rows, vtk.hpp).
  void write_frame(double time, const std::vector<FieldView>& fields);
  /// The checks write_frame makes of a serial frame before it writes
  /// anything (names, shapes, NaN or Inf, the range of a single-precision
  /// file), with the same exceptions, and nothing written. Reads only the
  /// writer's fixed settings: it may run while another thread writes
  /// through this writer (RunOptions::background_output).
  void check_frame(double time, const std::vector<FieldView>& fields) const;
  /// Appends one sample to `/probes/PROBE/time` and `/probes/PROBE/FIELD`
  /// (extendible datasets, `values` components per sample).
  void append_probe(const std::string& probe, double time,
                    const std::vector<std::pair<std::string, std::vector<double>>>& values);
  /// Appends one sample to the history `/GROUP/NAME/time` and
  /// `/GROUP/NAME/FIELD` (vector fields, as a probe; `group` is created
  /// on first use, e.g. "walls"). append_probe is the group "probes".
  void append_group_sample(const std::string& group, const std::string& name, double time,
                           const std::vector<std::pair<std::string, std::vector<double>>>& values);
  /// Appends one sample to the root-level time series `/SERIES/time` and
  /// `/SERIES/FIELD` (extendible rank-1 datasets, one scalar per field per
  /// sample; e.g. /energy/kinetic). Flushed like a probe sample.
  void append_series(const std::string& series, double time,
                     const std::vector<std::pair<std::string, double>>& values);
  void set_attribute(const std::string& name, double value);
  void set_attribute(const std::string& name, long long value);
  void set_attribute(const std::string& name, const std::string& value);
  /// Flushes everything to disk.
  void flush();
  /// Flushes and rewrites the XDMF sidecar so it names every frame written
  /// (it is otherwise rewritten at most every 0.25 s, and on destruction).
  void publish();
  const std::string& path() const { return path_; }
  int frames() const { return frames_; }
  /// The run id written into the file.
  const std::string& run_id() const;
  /// How the ranks write this file together (a serial file: the default).
  const ParallelIo& parallel() const;
  /// False once an HDF5 write to the file failed (nothing more is written to it).
  bool writable() const;

private:
  void flush_sample();
  /// One field's checks (check_frame); `seen`: the names so far.
  void check_field(const FieldView& f, double time, std::set<std::string>& seen) const;
  struct Impl;
  std::unique_ptr<Impl> impl_;
  std::string path_;
  int frames_ = 0;
};

/// One history a run appends a sample to at every output time: a probe
/// (/probes/NAME, vector fields) or a root-level series (/NAME, scalar fields).
struct HistoryLayout {
  std::string name;
  bool probe = true;           ///< a history of vector fields under `group`; false: a root-level series
  std::vector<std::string> fields; ///< the datasets besides time, in the order the run writes them
  std::string group = "probes";
  /// Datasets among `fields` that files written before they existed lack
  /// (a series a later version added): such a file's run booked none, so
  /// copy_results reads them as zeros.
  std::vector<std::string> zero_if_absent = {};
};

/// Continues a result file after a restart (checkpoint.hpp): appends to `to`
/// what the interrupted run wrote to the file `from` before its checkpoint -
/// frames 0 .. frames-1 (the datasets `frame_fields`, in that order) and the
/// first `frames` samples of each of `histories`, interleaved as a run writes
/// them (one sample of each history in the given order, then the frame). The
/// values are copied bit for bit (a parallel `to`: each rank reads and
/// writes its block of each frame's rows). Throws InputError naming `from`
/// when it cannot be read or holds fewer frames or samples.
void copy_results(const std::string& from, ResultWriter& to, int frames, const std::vector<HistoryLayout>& histories,
                  const std::vector<std::string>& frame_fields);

/// Reads a root attribute back (tests and tools). Throws InputError if the
/// path is empty, the file cannot be opened or the attribute is absent or of
/// another type; std::invalid_argument for an empty name.
std::string read_string_attribute(const std::string& path, const std::string& name);
double read_double_attribute(const std::string& path, const std::string& name);

} // namespace otmpm
