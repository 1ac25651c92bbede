#include "framework/checkpoint.hpp"

#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>

#include <fmt/format.h>

#include "framework/error.hpp"
#include "framework/files.hpp"
#include "framework/writers.hpp"

namespace weft {

static_assert(std::endian::native == std::endian::little, "checkpoints are written little-endian as in memory");

namespace {
constexpr char magic[8] = {'W', 'E', 'F', 'T', 'C', 'K', 'P', 'T'};
}

std::string Digest::hex() const { return fmt::format("{:016x}", h_); }

void require_finite(const Checkpoint& c, std::initializer_list<const char*> names) {
  for (const char* name : names) {
    if (!c.has(name)) continue;
    const auto& v = c.get(name);
    for (std::size_t i = 0; i < v.size(); ++i)
      if (!std::isfinite(v[i]))
        throw ConfigError(fmt::format("checkpoint array '{}' holds a non-finite value, {}, at index {}: the file is damaged", name, v[i], i));
  }
}

void Checkpoint::put(std::string name, std::vector<double> values) {
  WEFT_ASSERT(!has(name), "checkpoint array '{}' written twice", name);
  arrays.emplace_back(std::move(name), std::move(values));
}

bool Checkpoint::has(const std::string& name) const {
  for (const auto& [n, v] : arrays)
    if (n == name) return true;
  return false;
}

const std::vector<double>& Checkpoint::get(const std::string& name, long long expected_size) const {
  for (const auto& [n, v] : arrays)
    if (n == name) {
      if (expected_size >= 0 && static_cast<long long>(v.size()) != expected_size)
        throw ConfigError(fmt::format("checkpoint array '{}' holds {} values; this scene needs {}", name, v.size(), expected_size));
      return v;
    }
  throw ConfigError(fmt::format("checkpoint has no array '{}'", name));
}

namespace {
/// The arrays' names and bytes: a damaged or edited data section is refused on read.
std::string data_digest(const std::vector<std::pair<std::string, std::vector<double>>>& arrays) {
  Digest d;
  for (const auto& [name, v] : arrays) d.add(name.data(), name.size()).add(v.data(), v.size() * sizeof(double));
  return d.hex();
}
}  // namespace

void write_checkpoint(const std::string& path, const Checkpoint& c) {
  Json header = c.header;
  header["format"] = Checkpoint::format;
  Json table = Json::array();
  for (const auto& [name, v] : c.arrays) table.push_back({{"name", name}, {"size", v.size()}});
  header["arrays"] = table;
  header["digest"] = data_digest(c.arrays);
  const std::string text = header.dump();
  const std::uint64_t length = text.size();
  AtomicFile f(path);
  auto& out = f.stream();
  out.write(magic, sizeof magic);
  out.write(reinterpret_cast<const char*>(&length), sizeof length);
  out.write(text.data(), static_cast<std::streamsize>(text.size()));
  for (const auto& [name, v] : c.arrays)
    out.write(reinterpret_cast<const char*>(v.data()), static_cast<std::streamsize>(v.size() * sizeof(double)));
  f.commit();
}

Checkpoint read_checkpoint(const std::string& path) {
  require_regular_file(path, "checkpoint file", "a checkpoint (.wckp)");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw ConfigError(fmt::format("checkpoint {}: cannot open the file", path));
  in.seekg(0, std::ios::end);
  const auto file_size = static_cast<std::uint64_t>(in.tellg());
  in.seekg(0);
  const auto fail = [&](const std::string& why) { return ConfigError(fmt::format("checkpoint {}: {}", path, why)); };
  char m[8] = {};
  std::uint64_t length = 0;
  if (!in.read(m, sizeof m) || std::memcmp(m, magic, sizeof magic) != 0)
    throw fail("not a weft checkpoint (the file does not start with WEFTCKPT)");
  if (!in.read(reinterpret_cast<char*>(&length), sizeof length) || length > file_size - 16) throw fail("truncated or corrupt header length");
  std::string text(length, '\0');
  if (!in.read(text.data(), static_cast<std::streamsize>(length))) throw fail("truncated header");
  Checkpoint c;
  try {
    c.header = Json::parse(text);
  } catch (const Json::parse_error& e) {
    throw fail(fmt::format("header is not JSON: {}", e.what()));
  }
  if (!c.header.is_object() || !c.header.contains("format") || !c.header["format"].is_number_integer())
    throw fail("header has no integer 'format'");
  if (c.header["format"].get<int>() != Checkpoint::format)
    throw fail(fmt::format("format {} is not supported (this build reads format {})", c.header["format"].dump(), Checkpoint::format));
  if (!c.header.contains("arrays") || !c.header["arrays"].is_array()) throw fail("header has no 'arrays' table");
  for (const Json& a : c.header["arrays"]) {
    if (!a.is_object() || !a.contains("name") || !a["name"].is_string() || !a.contains("size") || !a["size"].is_number_unsigned())
      throw fail(fmt::format("malformed entry {} of the 'arrays' table", a.dump()));
    const auto n = a["size"].get<std::uint64_t>();
    const auto at = static_cast<std::uint64_t>(in.tellg());
    if (n > (file_size - at) / sizeof(double))
      throw fail(fmt::format("truncated data: array '{}' should hold {} values, the file has room for {}", a["name"].get<std::string>(), n,
                             (file_size - at) / sizeof(double)));
    std::vector<double> v(n);
    in.read(reinterpret_cast<char*>(v.data()), static_cast<std::streamsize>(n * sizeof(double)));
    c.arrays.emplace_back(a["name"].get<std::string>(), std::move(v));
  }
  if (in.peek() != std::char_traits<char>::eof()) throw fail("trailing bytes after the last array");
  if (c.header.contains("digest")) {  // checkpoints of older builds have none
    if (!c.header["digest"].is_string() || c.header["digest"].get<std::string>() != data_digest(c.arrays))
      throw fail("its data does not match the digest in its header: the file is damaged");
    c.header.erase("digest");
  }
  c.header.erase("arrays");
  c.header.erase("format");
  return c;
}

}  // namespace weft
