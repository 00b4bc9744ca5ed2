// The in-memory state of a run (state.hpp): accessors that turn a missing or
// misshapen item into an InputError naming the checkpoint, group and item.
#include "otmpm/state.hpp"

#include "otmpm/core.hpp"

namespace otmpm {

namespace {

template <class Map>
const typename Map::mapped_type& lookup(const StateGroup& g, const Map& map, const std::string& name,
                                        const char* kind) {
  const auto it = map.find(name);
  if (it == map.end()) g.error("missing " + std::string(kind) + " '" + name + "'");
  return it->second;
}

template <class T>
const StateArray<T>& shaped(const StateGroup& g, const StateArray<T>& a, const std::string& name, std::size_t rows,
                            std::size_t cols) {
  if (a.cols != cols || a.values.size() != rows * cols)
    g.error("array '" + name + "' holds " + std::to_string(a.values.size()) + " values in rows of " +
            std::to_string(a.cols) + ", expected " + std::to_string(rows) + " x " + std::to_string(cols));
  return a;
}

} // namespace

double StateGroup::real(const std::string& name) const { return lookup(*this, reals, name, "value"); }

std::int64_t StateGroup::integer(const std::string& name) const { return lookup(*this, integers, name, "integer"); }

const std::string& StateGroup::string(const std::string& name) const {
  return lookup(*this, strings, name, "string");
}

const StateArray<double>& StateGroup::real_array(const std::string& name, std::size_t rows, std::size_t cols) const {
  return shaped(*this, lookup(*this, real_arrays, name, "array"), name, rows, cols);
}

const StateArray<std::int64_t>& StateGroup::integer_array(const std::string& name, std::size_t rows,
                                                          std::size_t cols) const {
  return shaped(*this, lookup(*this, integer_arrays, name, "integer array"), name, rows, cols);
}

bool StateGroup::has_array(const std::string& name) const {
  return real_arrays.count(name) > 0 || integer_arrays.count(name) > 0;
}

void StateGroup::error(const std::string& message) const { throw InputError(where + ": " + message); }

StateGroup& Checkpoint::group(const std::string& name) {
  StateGroup& g = groups[name];
  if (g.where.empty()) g.where = (file.empty() ? std::string("checkpoint") : file) + ": group '" + name + "'";
  return g;
}

const StateGroup& Checkpoint::group(const std::string& name) const {
  const auto it = groups.find(name);
  if (it == groups.end()) throw InputError(file + ": incomplete checkpoint: no group '" + name + "'");
  return it->second;
}

} // namespace otmpm
