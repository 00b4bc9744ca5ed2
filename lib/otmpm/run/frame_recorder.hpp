#pragma once
/// \file frame_recorder.hpp
/// The frames of a run (internal to run/).
#include "otmpm/distributed/global_view.hpp"
#include "otmpm/engine/engine.hpp"
#include "otmpm/io/hdf5.hpp"
#include "otmpm/io/undo_journal.hpp"
#include "otmpm/parallel.hpp"
#include "otmpm/particles/output_fields.hpp"
#include "otmpm/run/output_time.hpp"

#include <algorithm>
#include <string>
#include <vector>

namespace otmpm {

/// Records the frames of the result file (/frames/NNNNNN): the fields of
/// output.fields of every particle in global order, symmetric tensors by
/// their independent components when output.symmetric_tensors asks (2D:
/// with plane strain's sigma_zz), a distributed run's rows as this rank's
/// block of the frame.
template <int D> class FrameRecorder {
public:
  FrameRecorder(const OutputSection& output, const Engine<D>& e, const distributed::GlobalView<D>& view)
      : output_(output), e_(e), view_(view) {}

  /// A restart continues the 2D symmetric stress of the interrupted run's
  /// file as it is: with sigma_zz, or with 3 columns in a file an otmpm before
  /// sigma_zz wrote.
  void continue_file(const std::string& path, long long frames) {
    if (D == 2 && output_.symmetric_tensors && frames > 0) plane_zz_ = !legacy_plane_stress(path);
  }

  /// Fills o.fields (with o.buffers and o.packed) with the frame of now.
  void fill(OutputTime& o) const {
    o.buffers.resize(output_.fields.size());
    o.packed.resize(o.buffers.size());
    o.fields = fields(o.buffers, o.packed);
  }

  /// Makes the frame's fields own their values (background output): the
  /// fields that point into the particle arrays are copied into their buffers.
  static void own_fields(OutputTime& o) {
    for (std::size_t i = 0; i < o.fields.size(); ++i) {
      FieldView& f = o.fields[i];
      if (!f.data || f.data == o.buffers[i].data() || f.data == o.packed[i].data()) continue;
      std::vector<double>& b = o.buffers[i];
      const double* from = f.data;
      b.resize(static_cast<std::size_t>(f.rows) * static_cast<std::size_t>(f.cols));
      parallel_chunks(static_cast<long long>(b.size()), [&](long long begin, long long end) {
        std::copy(from + begin, from + end, b.begin() + begin);
      });
      f.data = b.data();
    }
  }

private:
  /// One field's values (plain, or packed as symmetric components) and its
  /// component names ("" for the plain layout).
  struct Packed {
    FieldData data;
    std::string components;
  };

  /// The output fields of all particles in global order (buffers hold the
  /// values that are not stored as they are written); a distributed run:
  /// this rank's block of rows of the frame (collective).
  std::vector<FieldView> fields(std::vector<std::vector<double>>& buffers,
                                std::vector<std::vector<double>>& packed) const {
    const Particles<D>& P = e_.particles();
    std::vector<double> zz; // plane strain's sigma_zz, when a field of the frame holds it
    std::vector<FieldView> out;
    for (std::size_t i = 0; i < output_.fields.size(); ++i) {
      const std::string& name = output_.fields[i];
      const Packed d = field(name, zz, buffers[i], packed[i]);
      if (!view_.distributed()) {
        out.push_back({name, P.size(), d.data.cols, d.data.data, -1, 0, d.components});
        continue;
      }
      auto block = view_.block(d.data.data, d.data.cols); // this rank's rows of the frame, in global order
      buffers[i] = std::move(block.values);
      out.push_back({name, static_cast<int>(block.count), d.data.cols, buffers[i].data(), view_.particles(),
                     block.first, d.components});
    }
    return out;
  }

  /// The values of the field `name` (zz: sigma_zz, computed by the first field that needs it).
  Packed field(const std::string& name, std::vector<double>& zz, std::vector<double>& buffer,
               std::vector<double>& packed) const {
    const auto n = static_cast<std::size_t>(e_.particles().size());
    const bool symmetric = output_.symmetric_tensors && is_symmetric_tensor_field(name);
    const bool packed_zz = D == 2 && symmetric && name == "stress" && plane_zz_;
    if (D == 2 && zz.empty() && (name == kStressZzField || packed_zz)) zz = out_of_plane_stress();
    FieldData d;
    if (name == kStressZzField) {
      buffer = zz;
      d = {buffer.data(), 1};
    } else {
      d = output_field_data<D>(name, e_.particles(), buffer);
    }
    if (packed_zz) { // output.symmetric_tensors: and sigma_zz
      pack_plane_stress(d.data, zz.data(), n, packed);
      return {{packed.data(), 4}, std::string(plane_stress_components())};
    }
    if (symmetric) { // output.symmetric_tensors
      pack_symmetric(d.data, n, D, packed);
      return {{packed.data(), D * (D + 1) / 2}, std::string(symmetric_components(D))};
    }
    return {d, ""};
  }

  /// Plane strain's sigma_zz of every particle (2D), from each run of
  /// particles of one material (Material::out_of_plane_stress).
  std::vector<double> out_of_plane_stress() const {
    const Particles<D>& P = e_.particles();
    std::vector<double> zz(static_cast<std::size_t>(P.size()));
    for (int p0 = 0; p0 < P.size();) {
      const int id = P.material[p0];
      int p1 = p0 + 1;
      while (p1 < P.size() && P.material[p1] == id) ++p1;
      e_.material(id).out_of_plane_stress(P, p0, p1, zz.data() + p0);
      p0 = p1;
    }
    return zz;
  }

  /// True when the first frame of the result file `path` stores the 2D
  /// stress as "xx xy yy", as otmpm did before it stored plane strain's
  /// sigma_zz (false when there is no such frame or attribute).
  static bool legacy_plane_stress(const std::string& path) {
    h5::silence();
    const hid_t id = h5::open_result_read_only(path);
    if (id < 0) return false; // copy_results says why
    const h5::Handle file(id, H5Fclose);
    if (!h5::has_link(file.get(), "frames") || !h5::has_link(file.get(), "frames/000000") ||
        !h5::has_link(file.get(), "frames/000000/stress"))
      return false;
    try {
      const h5::Handle set(
          h5::checked(H5Dopen2(file.get(), "frames/000000/stress", H5P_DEFAULT), path, "open stress"), H5Dclose);
      return h5::has_attribute(set.get(), "components") && h5::read_string(set.get(), "components", path) == "xx xy yy";
    } catch (const h5::Failure&) {
      return false; // a damaged file: copy_results says why
    }
  }

  const OutputSection& output_;
  const Engine<D>& e_;
  const distributed::GlobalView<D>& view_;
  bool plane_zz_ = true; ///< 2D symmetric stress with sigma_zz (false: a restart of a file without it)
};

} // namespace otmpm
