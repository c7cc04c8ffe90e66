// Checked reading of JSON input (the scene-file reader's helpers): each
// function takes the value's JSON path and throws InputError naming it and
// what is wrong.
#pragma once

#include <nlohmann/json.hpp>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <initializer_list>
#include <limits>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace plm::scene_input {

using json = nlohmann::json;

// A rejected input; what() is the whole message.
struct InputError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

[[noreturn]] inline void fail(const std::string& path, const std::string& message) {
  throw InputError(path + ": " + message);
}

inline std::string index_path(const std::string& path, size_t i) { return path + "[" + std::to_string(i) + "]"; }

inline std::string json_quoted(std::string_view s) {
  std::string q = json(std::string(s)).dump(-1, ' ', false, json::error_handler_t::replace);
  if (q.size() > 60) q = q.substr(0, 56) + "...\"";
  return q;
}

// How a value is shown after "got": short, one line.
inline std::string shown(const json& v) {
  switch (v.type()) {
    case json::value_t::object: return "an object";
    case json::value_t::array: return "an array";
    case json::value_t::null: return "null";
    case json::value_t::string: return json_quoted(v.get_ref<const std::string&>());
    case json::value_t::number_float:
      if (!std::isfinite(v.get<double>())) return "a number out of range";
      [[fallthrough]];
    default: {
      std::string s = v.dump(-1, ' ', false, json::error_handler_t::replace);
      if (s.size() > 40) s = s.substr(0, 37) + "...";
      return s;
    }
  }
}

[[noreturn]] inline void expected(const std::string& path, const char* what, const json& v) {
  fail(path, std::string("expected ") + what + ", got " + shown(v));
}

// Rejects keys other than the allowed ones: misspelt fields never pass silently.
inline void check_keys(const json& obj, const std::string& path, std::initializer_list<const char*> allowed) {
  for (auto it = obj.begin(); it != obj.end(); ++it) {
    bool known = false;
    for (const char* a : allowed) known = known || it.key() == a;
    if (!known) {
      std::string list;
      for (const char* a : allowed) list += std::string(list.empty() ? "" : ", ") + a;
      fail(path + "." + it.key(), "unknown field (allowed: " + list + ")");
    }
  }
}

inline const json& object(const json& v, const std::string& path) {
  if (!v.is_object()) expected(path, "an object", v);
  return v;
}

inline const json& array(const json& v, const std::string& path, uint64_t max_count, const char* what = "elements") {
  if (!v.is_array()) expected(path, "an array", v);
  if (v.size() > max_count)
    fail(path, std::to_string(v.size()) + " " + what + " exceed the limit of " + std::to_string(max_count));
  return v;
}

inline const json* optional(const json& obj, const char* key) {
  auto it = obj.find(key);
  return it == obj.end() ? nullptr : &*it;
}

inline const json& required(const json& obj, const std::string& path, const char* key) {
  auto it = obj.find(key);
  if (it == obj.end()) fail(path, std::string("missing field \"") + key + "\"");
  return *it;
}

inline double number(const json& v, const std::string& path) {
  if (!v.is_number()) expected(path, "a number", v);
  const double d = v.get<double>();
  if (!std::isfinite(d)) fail(path, "expected a finite number, got a number out of range");
  return d;
}

inline float to_float(const json& v, const std::string& path) {
  const double d = number(v, path);
  if (std::fabs(d) > double(std::numeric_limits<float>::max()))
    fail(path, "the number " + shown(v) + " is out of the range of a 32-bit float");
  return float(d);
}

// A non-negative integer (an integral float such as 1e6 is fine) at most max.
inline uint64_t integer(const json& v, const std::string& path, uint64_t max) {
  if (!v.is_number()) expected(path, "an integer", v);
  uint64_t u = 0;
  if (v.is_number_unsigned()) {
    u = v.get<uint64_t>();
  } else if (v.is_number_integer()) {
    fail(path, "expected an integer >= 0, got " + shown(v));
  } else {
    const double d = v.get<double>();
    if (!std::isfinite(d) || d != std::floor(d)) expected(path, "an integer", v);
    if (d < 0) fail(path, "expected an integer >= 0, got " + shown(v));
    if (d >= 18446744073709551616.0) fail(path, shown(v) + " exceeds the limit of " + std::to_string(max));
    u = uint64_t(d);
  }
  if (u > max) fail(path, shown(v) + " exceeds the limit of " + std::to_string(max));
  return u;
}

inline uint32_t u32(const json& v, const std::string& path, uint32_t max = std::numeric_limits<uint32_t>::max()) {
  return uint32_t(integer(v, path, max));
}

inline const std::string& string(const json& v, const std::string& path) {
  if (!v.is_string()) expected(path, "a string", v);
  return v.get_ref<const std::string&>();
}

inline uint32_t enum_value(const json& v, const std::string& path, std::initializer_list<const char*> names) {
  const std::string& s = string(v, path);
  uint32_t i = 0;
  std::string list;
  for (const char* n : names) {
    if (s == n) return i;
    list += std::string(list.empty() ? "" : ", ") + n;
    ++i;
  }
  fail(path, json_quoted(s) + " is not one of " + list);
}

// An RGB colour: [r, g, b] or one number for grey.
inline void rgb(const json& v, const std::string& path, float out[3]) {
  if (v.is_number()) {
    out[0] = out[1] = out[2] = to_float(v, path);
    return;
  }
  if (!v.is_array()) expected(path, "[r, g, b] or a number", v);
  if (v.size() != 3) fail(path, "expected 3 numbers [r, g, b], got " + std::to_string(v.size()));
  for (size_t c = 0; c < 3; ++c) out[c] = to_float(v[c], index_path(path, c));
}

inline void fixed_floats(const json& v, const std::string& path, size_t n, float* out) {
  if (!v.is_array()) expected(path, "an array", v);
  if (v.size() != n) fail(path, "expected " + std::to_string(n) + " numbers, got " + std::to_string(v.size()));
  for (size_t i = 0; i < n; ++i) out[i] = to_float(v[i], index_path(path, i));
}

inline std::string name_or(const json& obj, const std::string& path, const std::string& fallback) {
  const json* n = optional(obj, "name");
  return n ? string(*n, path + ".name") : fallback;
}

// A reference to an earlier item: its index or its (unique) name.
inline uint32_t reference(const json& v, const std::string& path, const std::vector<std::string>& names, const char* list) {
  if (v.is_string()) {
    const std::string& s = v.get_ref<const std::string&>();
    int64_t found = -1;
    for (size_t i = 0; i < names.size(); ++i) {
      if (names[i] != s) continue;
      if (found >= 0) fail(path, json_quoted(s) + " is ambiguous: several of " + list + " have that name");
      found = int64_t(i);
    }
    if (found < 0) fail(path, json_quoted(s) + " is not the name of one of " + list);
    return uint32_t(found);
  }
  if (!v.is_number()) expected(path, "a name or an index", v);
  const uint64_t i = integer(v, path, std::numeric_limits<uint32_t>::max());
  if (i >= names.size())
    fail(path, "index " + std::to_string(i) + " is out of range (" + list + " has " + std::to_string(names.size()) +
                   ")");
  return uint32_t(i);
}

// Engine errors carry the path of the object being added.
// Vertex indices, each checked against the mesh's vertex count.
inline std::vector<uint32_t> vertex_indices(const json& v, const std::string& path, size_t vertex_count) {
  std::vector<uint32_t> out(v.size());
  for (size_t k = 0; k < v.size(); ++k) {
    const std::string pk = index_path(path, k);
    const uint64_t x = integer(v[k], pk, std::numeric_limits<uint32_t>::max());
    if (x >= vertex_count)
      fail(pk, "vertex index " + std::to_string(x) + " is out of range (the mesh has " +
                   std::to_string(vertex_count) + " vertices)");
    out[k] = uint32_t(x);
  }
  return out;
}


inline bool read_file(const std::string& path, uint64_t max_bytes, std::string& text, std::string& error) {
  FILE* f = std::fopen(path.c_str(), "rb");
  if (!f) {
    error = path + ": cannot open: " + std::strerror(errno);
    return false;
  }
  text.clear();
  char buf[65536];
  size_t n;
  while ((n = std::fread(buf, 1, sizeof buf, f)) > 0) {
    if (text.size() + n > max_bytes) {
      std::fclose(f);
      error = path + ": the file is larger than the limit of " + std::to_string(max_bytes) + " bytes";
      return false;
    }
    text.append(buf, n);
  }
  const bool bad = std::ferror(f);
  std::fclose(f);
  if (bad) {
    error = path + ": read error";
    return false;
  }
  return true;
}

}  // namespace plm::scene_input
