/// \file step.cpp
#include "otmpm/engine/step.hpp"

#include <stdexcept>

namespace otmpm {

double IntegratorParameters::get(std::string_view key) const {
  const auto it = values.find(key);
  require<std::invalid_argument>(it != values.end(), "IntegratorParameters: no parameter '", std::string(key), "'");
  return it->second;
}

} // namespace otmpm
