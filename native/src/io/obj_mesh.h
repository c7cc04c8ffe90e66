// Wavefront OBJ meshes referenced by scene files (docs/scene-file.md): the
// faces (fan-triangulated), the per-corner UVs where a lightmap needs them and
// the usemtl material of each triangle; errors name the file and line.
#pragma once

#include <string>
#include <vector>

#include "io/json_input.h"
#include "io/scene_file.h"

namespace plm::scene_input {

struct ObjMesh {
  std::vector<float> positions, uv;  // uv per triangle corner (empty if the mesh needs none)
  std::vector<uint32_t> indices, materials;
  bool usemtl = false;  // some face follows a usemtl
};

struct ObjReader {
  const std::string& file;
  const SceneFileLimits& limits;
  const std::vector<std::string>& material_names;
  bool need_uv;
  uint32_t material;  // before any usemtl
  size_t line = 0;
  std::vector<float> vt;  // u, v pairs

  [[noreturn]] void bad(const std::string& message) const {
    throw InputError(file + ":" + std::to_string(line) + ": " + message);
  }

  static std::vector<std::string_view> split(std::string_view s) {
    std::vector<std::string_view> out;
    size_t i = 0;
    while (i < s.size()) {
      while (i < s.size() && (s[i] == ' ' || s[i] == '\t' || s[i] == '\r' || s[i] == '\v' || s[i] == '\f')) ++i;
      const size_t b = i;
      while (i < s.size() && !(s[i] == ' ' || s[i] == '\t' || s[i] == '\r' || s[i] == '\v' || s[i] == '\f')) ++i;
      if (i > b) out.push_back(s.substr(b, i - b));
    }
    return out;
  }

  float real(std::string_view tok) const {
    const std::string t(tok);
    char* end = nullptr;
    errno = 0;
    const double d = std::strtod(t.c_str(), &end);
    if (t.empty() || *end) bad("\"" + t.substr(0, 40) + "\" is not a number");
    if (!std::isfinite(d) || std::fabs(d) > double(std::numeric_limits<float>::max()))
      bad("\"" + t.substr(0, 40) + "\" is not a finite 32-bit float");
    return float(d);
  }

  // A 1-based OBJ index (negative: relative to the end) into count items.
  uint32_t index(std::string_view tok, size_t count, const char* what) const {
    const std::string t(tok);
    char* end = nullptr;
    errno = 0;
    const long long i = std::strtoll(t.c_str(), &end, 10);
    if (t.empty() || *end || errno == ERANGE) bad(std::string(what) + " index \"" + t.substr(0, 40) + "\" is not an integer");
    if (i == 0) bad(std::string(what) + " index 0 (OBJ indices start at 1)");
    const long long r = i > 0 ? i - 1 : (long long)count + i;
    if (r < 0 || r >= (long long)count)
      bad(std::string(what) + " index " + t + " is out of range (" + std::to_string(count) + " so far)");
    return uint32_t(r);
  }

  ObjMesh read(std::string_view text) {
    ObjMesh m;
    uint32_t current = material;
    size_t pos = 0;
    std::vector<uint32_t> face_v, face_t;
    while (pos < text.size()) {
      size_t eol = text.find('\n', pos);
      if (eol == std::string_view::npos) eol = text.size();
      std::string_view l = text.substr(pos, eol - pos);
      pos = eol + 1;
      ++line;
      const size_t hash = l.find('#');
      if (hash != std::string_view::npos) l = l.substr(0, hash);
      const std::vector<std::string_view> tok = split(l);
      if (tok.empty()) continue;
      const std::string_view key = tok[0];
      if (key == "v") {
        if (tok.size() < 4 || tok.size() > 7) bad("v needs 3 coordinates (x y z [w] or x y z r g b)");
        if (m.positions.size() / 3 >= limits.max_vertices)
          bad("more than " + std::to_string(limits.max_vertices) + " vertices");
        for (int c = 1; c <= 3; ++c) m.positions.push_back(real(tok[c]));
        for (size_t c = 4; c < tok.size(); ++c) real(tok[c]);
      } else if (key == "vt") {
        if (tok.size() < 2 || tok.size() > 4) bad("vt needs 1 to 3 coordinates (u [v [w]])");
        if (vt.size() / 2 >= limits.max_vertices)
          bad("more than " + std::to_string(limits.max_vertices) + " texture coordinates");
        vt.push_back(real(tok[1]));
        vt.push_back(tok.size() > 2 ? real(tok[2]) : 0.0f);
        if (tok.size() > 3) real(tok[3]);
      } else if (key == "f") {
        if (tok.size() < 4) bad("a face needs at least 3 vertices, got " + std::to_string(tok.size() - 1));
        face_v.clear();
        face_t.clear();
        for (size_t c = 1; c < tok.size(); ++c) {
          const std::string_view corner = tok[c];
          const size_t s1 = corner.find('/');
          face_v.push_back(index(corner.substr(0, s1), m.positions.size() / 3, "vertex"));
          std::string_view t;
          if (s1 != std::string_view::npos) {
            const size_t s2 = corner.find('/', s1 + 1);
            t = corner.substr(s1 + 1, s2 == std::string_view::npos ? std::string_view::npos : s2 - s1 - 1);
            if (s2 != std::string_view::npos && corner.find('/', s2 + 1) != std::string_view::npos)
              bad("face corner \"" + std::string(corner.substr(0, 40)) + "\" has more than 3 parts");
          }
          if (t.empty()) {
            if (need_uv)
              bad("face corner " + std::to_string(c) + " has no texture coordinate (vt), which the lightmap needs");
          } else {
            face_t.push_back(index(t, vt.size() / 2, "texture coordinate"));
          }
        }
        const size_t new_tris = face_v.size() - 2;
        if (m.indices.size() / 3 + new_tris > limits.max_triangles)
          bad("more than " + std::to_string(limits.max_triangles) + " triangles");
        for (size_t k = 1; k + 1 < face_v.size(); ++k) {  // fan
          const size_t corners[3] = {0, k, k + 1};
          for (size_t c : corners) {
            m.indices.push_back(face_v[c]);
            if (need_uv) {
              m.uv.push_back(vt[2 * face_t[c]]);
              m.uv.push_back(vt[2 * face_t[c] + 1]);
            }
          }
          m.materials.push_back(current);
        }
        m.usemtl = m.usemtl || current != material;
      } else if (key == "usemtl") {
        if (tok.size() != 2) bad("usemtl needs one material name");
        const std::string name(tok[1]);
        bool found = false;
        for (size_t i = 0; i < material_names.size() && !found; ++i)
          if (material_names[i] == name) {
            current = uint32_t(i);
            found = true;
          }
        if (!found) bad("usemtl " + json_quoted(name) + ": the scene has no material of that name (scene.materials)");
      }
      // Everything else (vn, vp, o, g, s, mtllib, l, p, curves...) does not concern a lightmap.
    }
    if (m.indices.empty()) bad("no faces in the file");
    return m;
  }
};

}  // namespace plm::scene_input
