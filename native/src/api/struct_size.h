// The layouts of the C API's caller-allocated structs, told apart by their
// leading struct_size (photonlm.h, "Struct sizes"). A struct only grows at its
// end, so every layout is a prefix of the current one; Layouts<T> lists the
// sizes the library knows, oldest first. The API reads a caller's struct into
// a whole current one (the fields the caller's layout lacks keep their
// defaults) and writes only the caller's prefix.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>

#include "photonlm/photonlm.h"
#include "util/error.h"

namespace plm::api {

// sizeof an older layout of T that ended before the field at `offset`: the
// offset rounded up to T's alignment, as the caller's compiler pads it.
template <typename T>
constexpr uint32_t size_before(size_t offset) {
  return uint32_t((offset + alignof(T) - 1) / alignof(T) * alignof(T));
}

template <typename T>
struct Layouts;

#define PLM_LAYOUTS(T, ...)                            \
  template <>                                          \
  struct Layouts<T> {                                  \
    static constexpr const char* name = #T;            \
    static constexpr uint32_t sizes[] = {__VA_ARGS__}; \
  }

PLM_LAYOUTS(plm_bake_settings, size_before<plm_bake_settings>(offsetof(plm_bake_settings, texel_value)),
            size_before<plm_bake_settings>(offsetof(plm_bake_settings, directional)), uint32_t(sizeof(plm_bake_settings)));
PLM_LAYOUTS(plm_bake_stats, size_before<plm_bake_stats>(offsetof(plm_bake_stats, error_above)),
            size_before<plm_bake_stats>(offsetof(plm_bake_stats, error_worst)), uint32_t(sizeof(plm_bake_stats)));
PLM_LAYOUTS(plm_lobe, size_before<plm_lobe>(offsetof(plm_lobe, weight)), uint32_t(sizeof(plm_lobe)));
PLM_LAYOUTS(plm_light, uint32_t(sizeof(plm_light)));
PLM_LAYOUTS(plm_csg_primitive, uint32_t(sizeof(plm_csg_primitive)));
PLM_LAYOUTS(plm_csg_node, uint32_t(sizeof(plm_csg_node)));
PLM_LAYOUTS(plm_ol_stats, uint32_t(sizeof(plm_ol_stats)));
PLM_LAYOUTS(plm_lsystem_settings, uint32_t(sizeof(plm_lsystem_settings)));
PLM_LAYOUTS(plm_lsystem_stats, uint32_t(sizeof(plm_lsystem_stats)));

#undef PLM_LAYOUTS

// The list of T's layouts for an error message: "96 or 104".
template <typename T>
std::string layout_list() {
  std::string s;
  const size_t n = sizeof(Layouts<T>::sizes) / sizeof(uint32_t);
  for (size_t i = 0; i < n; ++i) {
    if (i > 0) s += i + 1 == n ? " or " : ", ";
    s += std::to_string(Layouts<T>::sizes[i]);
  }
  return s;
}

// `size`, the struct_size of a caller's T (`what` names it in `function`'s
// errors), if it is one of T's layouts; else PLM_ERROR_STRUCT_SIZE.
template <typename T>
uint32_t checked_size(uint32_t size, const char* function, const std::string& what) {
  for (uint32_t known : Layouts<T>::sizes)
    if (size == known) return size;
  const uint32_t current = uint32_t(sizeof(T));
  const char* why = size > current ? "larger than this library's" : "not a layout this library knows";
  fail(PLM_ERROR_STRUCT_SIZE, function, ": ", what, " (", Layouts<T>::name, ") has struct_size ", size, ", ", why,
       " (current ", current, "; known ", layout_list<T>(), "): set it to sizeof(", Layouts<T>::name, ")");
}

// A caller's T at `in` read as far as its layout goes, over `defaults`.
template <typename T>
T read_sized(const T* in, const T& defaults, const char* function, const std::string& what) {
  const uint32_t size = checked_size<T>(in->struct_size, function, what);
  T out = defaults;
  std::memcpy(static_cast<void*>(&out), in, size);
  out.struct_size = uint32_t(sizeof(T));
  return out;
}

// `value` written to the caller's T at `out` as far as its layout goes; its
// struct_size is left as the caller set it.
template <typename T>
void write_sized(T* out, const T& value, const char* function, const std::string& what) {
  const uint32_t size = checked_size<T>(out->struct_size, function, what);
  constexpr size_t skip = sizeof(uint32_t);  // struct_size
  std::memcpy(reinterpret_cast<unsigned char*>(out) + skip, reinterpret_cast<const unsigned char*>(&value) + skip,
              size - skip);
}

}  // namespace plm::api
