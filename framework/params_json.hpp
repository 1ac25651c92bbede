#pragma once
/// \file params_json.hpp
/// Visitors over `Params::visit` (see params.hpp) that read JSON strictly, write the
/// effective values back to JSON, and document every key.
#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include <array>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "framework/params.hpp"

namespace weft {

using Json = nlohmann::json;

/// Dotted key path ("cloths.0.material.thickness").
inline std::string join_path(const std::string& path, std::string_view key) {
  return path.empty() ? std::string(key) : path + "." + std::string(key);
}

/// Human-readable JSON value for messages.
inline std::string show(const Json& j) { return j.dump(); }

/// Reads a JSON object into a Params struct. Every problem (unknown key, wrong type,
/// unknown unit, value out of range, missing required key) is appended to `errors`; the
/// caller throws once with all of them.
class JsonReader {
 public:
  JsonReader(const Json& object, std::string path, std::vector<std::string>& errors)
      : obj_(object), path_(std::move(path)), errors_(errors) {
    if (!obj_.is_object()) {
      errors_.push_back(fmt::format("{} = {} has the wrong type: expected an object", path_.empty() ? "<root>" : path_, show(obj_)));
      valid_ = false;
    }
  }
  /// Keys the visit did not read; call after `visit` (reported as errors).
  void finish() {
    if (!valid_) return;
    for (auto it = obj_.begin(); it != obj_.end(); ++it)
      if (!used_.count(it.key()) && it.key().rfind("//", 0) != 0 && it.key().rfind("_comment", 0) != 0)
        errors_.push_back(fmt::format("{} is not a known key here (known: {})", join_path(path_, it.key()), known()));
  }
  bool has(const char* key) const { return valid_ && obj_.contains(key); }
  const std::string& path() const { return path_; }

  void field(const char* key, double& value, const FieldInfo& info) {
    const Json* j = lookup(key, info.required);
    if (!j) return;
    if (auto v = scalar(*j, join_path(path_, key), info)) value = *v;
  }
  void field(const char* key, std::optional<double>& value, const FieldInfo& info) {
    const Json* j = lookup(key, info.required);
    if (!j || j->is_null()) return;
    if (auto v = scalar(*j, join_path(path_, key), info)) value = *v;
  }
  void field(const char* key, int& value, const FieldInfo& info) {
    const Json* j = lookup(key, info.required);
    if (!j) return;
    const std::string p = join_path(path_, key);
    if (!j->is_number_integer()) return type_error(p, *j, "an integer");
    const auto v = j->get<long long>();
    if (!info.range.contains(static_cast<double>(v)))
      return errors_.push_back(fmt::format("{} = {} is out of range: valid {}", p, v, info.range.text()));
    value = static_cast<int>(v);
  }
  void field(const char* key, bool& value, const FieldInfo& info) {
    const Json* j = lookup(key, info.required);
    if (!j) return;
    if (!j->is_boolean()) return type_error(join_path(path_, key), *j, "true or false");
    value = j->get<bool>();
  }
  void field(const char* key, std::string& value, const FieldInfo& info) {
    const Json* j = lookup(key, info.required);
    if (!j) return;
    if (!j->is_string()) return type_error(join_path(path_, key), *j, "a string");
    value = j->get<std::string>();
  }
  template <int N>
  void field(const char* key, Eigen::Matrix<double, N, 1>& value, const FieldInfo& info) {
    const Json* j = lookup(key, info.required);
    if (!j) return;
    const std::string p = join_path(path_, key);
    if (!j->is_array() || j->size() != N) return type_error(p, *j, fmt::format("an array of {} numbers", N));
    Eigen::Matrix<double, N, 1> tmp = value;
    for (int i = 0; i < N; ++i) {
      auto v = scalar((*j)[i], fmt::format("{}.{}", p, i), info);
      if (!v) return;
      tmp[i] = *v;
    }
    value = tmp;
  }
  template <size_t N>
  void field(const char* key, std::array<int, N>& value, const FieldInfo& info) {
    const Json* j = lookup(key, info.required);
    if (!j) return;
    const std::string p = join_path(path_, key);
    if (!j->is_array() || j->size() != N) return type_error(p, *j, fmt::format("an array of {} integers", N));
    for (size_t i = 0; i < N; ++i) {
      if (!(*j)[i].is_number_integer()) return type_error(fmt::format("{}.{}", p, i), (*j)[i], "an integer");
      const auto v = (*j)[i].template get<long long>();
      if (!info.range.contains(static_cast<double>(v)))
        return errors_.push_back(fmt::format("{}.{} = {} is out of range: valid {}", p, i, v, info.range.text()));
      value[i] = static_cast<int>(v);
    }
  }
  void field(const char* key, std::vector<int>& value, const FieldInfo& info) {
    const Json* j = lookup(key, info.required);
    if (!j) return;
    const std::string p = join_path(path_, key);
    if (!j->is_array()) return type_error(p, *j, "an array of integers");
    std::vector<int> tmp;
    for (size_t i = 0; i < j->size(); ++i) {
      if (!(*j)[i].is_number_integer()) return type_error(fmt::format("{}.{}", p, i), (*j)[i], "an integer");
      const auto v = (*j)[i].template get<long long>();
      if (!info.range.contains(static_cast<double>(v)))
        return errors_.push_back(fmt::format("{}.{} = {} is out of range: valid {}", p, i, v, info.range.text()));
      tmp.push_back(static_cast<int>(v));
    }
    value = std::move(tmp);
  }
  template <class E, size_t N>
  void choice(const char* key, E& value, const std::array<std::string_view, N>& names, const char* /*doc*/,
              bool required = false) {
    const Json* j = lookup(key, required);
    if (!j) return;
    const std::string p = join_path(path_, key);
    if (!j->is_string()) return type_error(p, *j, fmt::format("one of {}", fmt::join(names, ", ")));
    const auto s = j->get<std::string>();
    for (size_t i = 0; i < N; ++i)
      if (names[i] == s) {
        value = static_cast<E>(i);
        return;
      }
    errors_.push_back(fmt::format("{} = \"{}\" is not a valid choice: valid are {}", p, s, fmt::join(names, ", ")));
  }
  template <class P>
  void section(const char* key, P& sub) {
    const Json* j = lookup(key, false);
    if (!j) return;
    JsonReader r(*j, join_path(path_, key), errors_);
    sub.visit(r);
    r.finish();
  }
  template <class P>
  void list(const char* key, std::vector<P>& items, const char* /*doc*/, int min_count = 0) {
    const Json* j = lookup(key, min_count > 0);
    if (!j) return;
    const std::string p = join_path(path_, key);
    if (!j->is_array()) return type_error(p, *j, "an array of objects");
    if (static_cast<int>(j->size()) < min_count)
      return errors_.push_back(fmt::format("{} has {} entries: at least {} required", p, j->size(), min_count));
    items.clear();
    for (size_t i = 0; i < j->size(); ++i) {
      P item{};
      JsonReader r((*j)[i], fmt::format("{}.{}", p, i), errors_);
      item.visit(r);
      r.finish();
      items.push_back(std::move(item));
    }
  }

 private:
  const Json* lookup(const char* key, bool required) {
    if (!valid_) return nullptr;
    used_.insert(key);
    auto it = obj_.find(key);
    if (it == obj_.end()) {
      if (required) errors_.push_back(fmt::format("{} is required but missing", join_path(path_, key)));
      return nullptr;
    }
    return &*it;
  }
  std::optional<double> scalar(const Json& j, const std::string& p, const FieldInfo& info) {
    double v = 0;
    if (j.is_number()) {
      v = j.get<double>();
    } else if (j.is_string()) {
      std::string err;
      auto q = parse_quantity(j.get<std::string>(), info.unit, err);
      if (!q) {
        errors_.push_back(fmt::format("{} = {}: {}", p, show(j), err));
        return std::nullopt;
      }
      v = *q;
    } else {
      type_error(p, j, info.unit == Unit::none ? std::string("a number")
                                               : fmt::format("a number in {} or a string with a unit", si_symbol(info.unit)));
      return std::nullopt;
    }
    if (!info.range.contains(v)) {
      errors_.push_back(fmt::format("{} = {}{}{} is out of range: valid {}{}{}", p, v, info.unit == Unit::none ? "" : " ",
                                    si_symbol(info.unit), info.range.text(), info.unit == Unit::none ? "" : " ",
                                    si_symbol(info.unit)));
      return std::nullopt;
    }
    return v;
  }
  void type_error(const std::string& p, const Json& j, const std::string& expected) {
    errors_.push_back(fmt::format("{} = {} has the wrong type: expected {}", p, show(j), expected));
  }
  std::string known() const {
    std::string s;
    for (const auto& k : used_) s += (s.empty() ? "" : ", ") + k;
    return s;
  }

  const Json& obj_;
  std::string path_;
  std::vector<std::string>& errors_;
  std::set<std::string> used_;
  bool valid_ = true;
};

/// Writes the effective parameters (SI values) as JSON.
class JsonWriter {
 public:
  explicit JsonWriter(Json& out) : out_(out) { out_ = Json::object(); }
  template <class T>
  void field(const char* key, const T& value, const FieldInfo&) { out_[key] = to_json(value); }
  template <class E, size_t N>
  void choice(const char* key, const E& value, const std::array<std::string_view, N>& names, const char*, bool = false) {
    out_[key] = std::string(enum_name(value, names));
  }
  template <class P>
  void section(const char* key, const P& sub) {
    Json j;
    JsonWriter w(j);
    const_cast<P&>(sub).visit(w);
    out_[key] = j;
  }
  template <class P>
  void list(const char* key, const std::vector<P>& items, const char*, int = 0) {
    Json arr = Json::array();
    for (const auto& it : items) {
      Json j;
      JsonWriter w(j);
      const_cast<P&>(it).visit(w);
      arr.push_back(j);
    }
    out_[key] = arr;
  }

 private:
  template <class T>
  static Json to_json(const T& v) {
    if constexpr (std::is_same_v<T, std::optional<double>>) return v ? Json(*v) : Json(nullptr);
    else if constexpr (std::is_base_of_v<Eigen::DenseBase<T>, T>) return std::vector<double>(v.data(), v.data() + v.size());
    else return Json(v);
  }
  Json& out_;
};

/// Markdown rows "| key | type | unit | default | valid | meaning |" for the reference.
class DocWriter {
 public:
  DocWriter(std::string path, std::vector<std::string>& rows) : path_(std::move(path)), rows_(rows) {}
  template <class T>
  void field(const char* key, const T& value, const FieldInfo& info) {
    row(key, type_name<T>(), std::string(si_symbol(info.unit)), info.required ? "required" : default_text(value, info),
        range_text<T>(info), info.doc);
  }
  template <class E, size_t N>
  void choice(const char* key, const E& value, const std::array<std::string_view, N>& names, const char* doc,
              bool required = false) {
    row(key, "string", "", required ? "required" : fmt::format("`{}`", enum_name(value, names)),
        fmt::format("{}", fmt::join(names, ", ")), doc);
  }
  template <class P>
  void section(const char* key, const P& sub) {
    DocWriter w(join_path(path_, key), rows_);
    const_cast<P&>(sub).visit(w);
  }
  template <class P>
  void list(const char* key, const std::vector<P>&, const char* doc, int min_count = 0) {
    row(key, "array of objects", "", min_count > 0 ? fmt::format("at least {}", min_count) : "[]", "", doc);
    P item{};
    DocWriter w(join_path(path_, key) + ".N", rows_);
    item.visit(w);
  }

 private:
  void row(const char* key, const std::string& type, const std::string& unit, const std::string& def,
           const std::string& valid, const char* doc) {
    rows_.push_back(fmt::format("| `{}` | {} | {} | {} | {} | {} |", join_path(path_, key), type, unit, def, valid, doc));
  }
  template <class T>
  static std::string type_name() {
    if constexpr (std::is_same_v<T, double> || std::is_same_v<T, std::optional<double>>) return "number";
    else if constexpr (std::is_same_v<T, int>) return "integer";
    else if constexpr (std::is_same_v<T, bool>) return "boolean";
    else if constexpr (std::is_same_v<T, std::string>) return "string";
    else if constexpr (std::is_same_v<T, std::vector<int>>) return "array of integers";
    else if constexpr (std::is_base_of_v<Eigen::DenseBase<T>, T>) return fmt::format("array of {} numbers", T::RowsAtCompileTime);
    else return fmt::format("array of {} integers", std::tuple_size_v<T>);
  }
  template <class T>
  static std::string range_text(const FieldInfo& info) {
    if constexpr (std::is_same_v<T, bool> || std::is_same_v<T, std::string>) return "";
    else return info.range.unbounded() ? "" : info.range.text();
  }
  template <class T>
  static std::string default_text(const T& v, const FieldInfo&) {
    if constexpr (std::is_same_v<T, std::optional<double>>) return v ? fmt::format("{}", *v) : "unset";
    else if constexpr (std::is_same_v<T, std::string>) return v.empty() ? "\"\"" : fmt::format("`\"{}\"`", v);
    else if constexpr (std::is_same_v<T, std::vector<int>>) return fmt::format("[{}]", fmt::join(v, ", "));
    else if constexpr (std::is_base_of_v<Eigen::DenseBase<T>, T>) return fmt::format("[{}]", fmt::join(v.data(), v.data() + v.size(), ", "));
    else if constexpr (std::is_same_v<T, int> || std::is_same_v<T, double> || std::is_same_v<T, bool>) return fmt::format("{}", v);
    else return fmt::format("[{}]", fmt::join(v, ", "));
  }
  std::string path_;
  std::vector<std::string>& rows_;
};

/// Read `Params` from a JSON object; throws one ConfigError listing every problem.
template <class P>
P read_params(const Json& j, const std::string& path, const std::string& header) {
  std::vector<std::string> errors;
  P p{};
  JsonReader r(j, path, errors);
  p.visit(r);
  r.finish();
  if (!errors.empty()) throw ConfigError(header, errors);
  return p;
}

template <class P>
Json write_params(const P& p) {
  Json j;
  JsonWriter w(j);
  const_cast<P&>(p).visit(w);
  return j;
}

}  // namespace weft
