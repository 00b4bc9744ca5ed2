#pragma once
/// \file output_time.hpp
/// What one output time writes into the result file, owned, so that the
/// writer thread may write it while the engine steps on (internal to run/).
#include "otmpm/io/results.hpp"

#include <string>
#include <utility>
#include <vector>

namespace otmpm {

/// Named samples of named histories: per probe its x, v and stress, per wall
/// its force and impulse.
using Samples = std::vector<std::pair<std::string, std::vector<std::pair<std::string, std::vector<double>>>>>;
/// The columns of one root-level series (/energy, /diagnostics) at one time.
using SeriesSample = std::vector<std::pair<std::string, double>>;

/// One output time: the samples of every history, then the frame.
struct OutputTime {
  double t = 0.0;
  Samples probes;           ///< ProbeSeries
  SeriesSample energy;      ///< EnergySeries
  SeriesSample diagnostics; ///< SupportSeries (empty when it is off)
  Samples walls;            ///< WallSeries
  std::vector<std::vector<double>> buffers, packed; ///< the frame's values not stored as they are written
  std::vector<FieldView> fields;                    ///< FrameRecorder
};

} // namespace otmpm
