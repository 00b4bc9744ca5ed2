// The message of an InputError a call throws, for the tests of input checks.
#pragma once

#include "otmpm/core.hpp"

#include <string>

namespace otmpm::test {

/// The message of the InputError that `call` throws ("" if none).
template <class F> std::string input_error_of(F&& call) {
  try {
    call();
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

} // namespace otmpm::test
