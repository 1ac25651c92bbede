#pragma once
/// \file checkpoint.hpp
/// Checkpoints: a simulator's state between two steps, exact to the bit, so that a run
/// resumes (`weft run --resume`) or a failing step replays with the same arithmetic.
///
/// File format (version 1), little-endian:
///   8 bytes  "WEFTCKPT"
///   8 bytes  uint64, length H of the header
///   H bytes  JSON header: {"format": 1, "arrays": [{"name", "size"}, ...], ...}; the other
///            keys belong to the writer (the simulator's "step", "time", "combo", sizes, and
///            `weft run`'s counters under "run")
///   then the arrays in header order, each `size` float64 values.
/// A reader in another language needs only the header: numpy.fromfile(f, '<f8', offset=16 + H).
#include <Eigen/Core>

#include <cstddef>
#include <initializer_list>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "framework/params_json.hpp"

namespace weft {

struct Checkpoint {
  static constexpr int format = 1;
  Json header = Json::object();                                   ///< writer's keys ("arrays" and "format" are added on write)
  std::vector<std::pair<std::string, std::vector<double>>> arrays;  ///< named float64 arrays, in file order

  /// Append an array (names must be unique).
  void put(std::string name, std::vector<double> values);
  void put(std::string name, const Eigen::VectorXd& values) { put(std::move(name), std::vector<double>(values.data(), values.data() + values.size())); }
  /// The array `name`; throws ConfigError naming the array when it is missing or when
  /// `expected_size` >= 0 and its size differs.
  const std::vector<double>& get(const std::string& name, long long expected_size = -1) const;
  bool has(const std::string& name) const;
  /// One value, as an array of size 1.
  void put_scalar(std::string name, double value) { put(std::move(name), std::vector<double>{value}); }
  double get_scalar(const std::string& name) const { return get(name, 1)[0]; }
};

/// A 64-bit FNV-1a digest of raw bytes, printed as 16 hex digits: it ties a checkpoint to
/// the mesh of the scene that wrote it (faces and rest positions, bit for bit), so that a
/// state is never resumed on another mesh that happens to have as many vertices.
class Digest {
 public:
  Digest& add(const void* data, std::size_t bytes) {
    const auto* p = static_cast<const unsigned char*>(data);
    for (std::size_t i = 0; i < bytes; ++i) h_ = (h_ ^ p[i]) * 1099511628211ull;
    return *this;
  }
  /// The coefficients of a dense Eigen object, in storage order.
  template <class M>
  Digest& add_matrix(const M& m) {
    return add(m.data(), static_cast<std::size_t>(m.size()) * sizeof(typename M::Scalar));
  }
  std::string hex() const;

 private:
  unsigned long long h_ = 14695981039346656037ull;
};

/// Every value of the named arrays is finite; throws ConfigError naming the array and the
/// first bad index otherwise (a state is always finite: a step that produced NaN fails).
void require_finite(const Checkpoint& c, std::initializer_list<const char*> names);

/// The state a cloth `Simulator`'s policy carries from one step to the next, in a
/// checkpoint. A policy takes part in checkpoints in one of two ways:
///  - it declares `static constexpr bool stateless = true`: nothing it holds between two
///    steps changes what the next step computes (caches rebuilt the same from the state,
///    such as a BVH whose output is sorted, or a symbolic factorisation of the same pattern);
///  - it has `save(Checkpoint&, std::string_view prefix) const`, which appends arrays named
///    `prefix` + name (and header keys under header[prefix]), and `restore(const
///    Checkpoint&, std::string_view prefix)`, which reads them back: arrays of the wrong
///    size are a ConfigError naming the array (the policy unchanged then); when all of
///    them are missing (a checkpoint of another combination, to replay a step with other
///    policies) the policy starts as at the start of a run.
/// A policy that does neither makes its combination refuse checkpoints: nothing is saved
/// by guess. It may also say, with `std::string resume_caveat() const`, why a resumed run
/// will not repeat the uninterrupted one to the bit (a kept preconditioner hierarchy is
/// rebuilt at the first solve after a restore); "" when it will.
template <class P>
concept StatelessPolicy = requires { requires P::stateless; };
template <class P>
concept SavesState = requires(const P& p, P& m, Checkpoint& c, const Checkpoint& cc, std::string_view prefix) {
  p.save(c, prefix);
  m.restore(cc, prefix);
};
template <class P>
concept CheckpointPolicy = StatelessPolicy<P> || SavesState<P>;

/// Write atomically (a temporary file renamed when complete); throws std::runtime_error on I/O failure.
void write_checkpoint(const std::string& path, const Checkpoint& c);
/// Read a checkpoint; throws ConfigError naming the file and what is wrong (missing file,
/// not a checkpoint, unknown format version, header that does not parse, truncated data).
Checkpoint read_checkpoint(const std::string& path);

}  // namespace weft
