// An L-system placed in a scene (lsystem/lsystem_object.h).
#include "lsystem/lsystem_object.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "csg/primitive.h"
#include "lsystem/graph/embree_callbacks.h"
#include "lsystem/graph/geometry.h"
#include "util/error.h"
#include "util/rng.h"

namespace plm::lsystem {
namespace {


// Checks that the placement is a similarity; returns its scale.
double check_placement(const double* m, const std::string& label) {
  for (int i = 0; i < 12; ++i) {
    if (!std::isfinite(m[i])) fail(PLM_ERROR_INVALID_ARGUMENT, label, ": matrix element ", i, " is not finite");
    if (std::fabs(m[i]) > 1e12) fail(PLM_ERROR_INVALID_ARGUMENT, label, ": matrix element ", i, " = ", m[i],
                                     " is beyond the engine's range of +-1e12");
  }
  const Affine3d a = Affine3d::from_array(m);
  const Vec3d c[3] = {a.column(0), a.column(1), a.column(2)};
  const double l[3] = {length(c[0]), length(c[1]), length(c[2])};
  const double s = (l[0] + l[1] + l[2]) / 3.0;
  if (!(s > 1e-12)) fail(PLM_ERROR_INVALID_ARGUMENT, label, ": matrix scales the object to nothing");
  constexpr double kTol = 1e-5;
  for (int i = 0; i < 3; ++i) {
    if (std::fabs(l[i] - s) > kTol * s)
      fail(PLM_ERROR_INVALID_ARGUMENT, label, ": matrix must be a rotation times a uniform scale (column ", i,
           " has length ", l[i], ", the mean is ", s, ")");
    for (int j = i + 1; j < 3; ++j)
      if (std::fabs(dot(c[i], c[j])) > kTol * s * s)
        fail(PLM_ERROR_INVALID_ARGUMENT, label, ": matrix has a shear (columns ", i, " and ", j, " are not orthogonal)");
  }
  return s;
}

GraphOptions graph_options(const plm_lsystem_settings& s) {
  GraphOptions o;
  o.depth = s.depth == 0 ? -1 : int(std::min<uint32_t>(s.depth, 1u << 20));
  o.seed = s.seed;
  o.step = s.step;
  o.angle = s.angle;
  o.width = s.width;
  o.cache_bytes = s.cache_bytes ? size_t(s.cache_bytes) : size_t(64) << 20;
  o.world = Affine3d::from_array(s.matrix);
  return o;
}

std::unique_ptr<Graph> build_graph(const char* rules, const plm_lsystem_settings& s, const std::string& label) {
  if (!rules) fail(PLM_ERROR_INVALID_ARGUMENT, label, ": rules must not be NULL");
  try {
    const LSystem system = parse(rules);
    return std::make_unique<Graph>(system, graph_options(s));
  } catch (const Error& e) {
    fail(e.status(), label, ": ", e.what());
  }
}

}  // namespace

plm_lsystem_settings default_lsystem_settings() {
  plm_lsystem_settings s{};
  s.struct_size = uint32_t(sizeof s);
  s.depth = 0;
  s.seed = 0;
  for (int i = 0; i < 12; ++i) s.matrix[i] = (i % 5 == 0) ? 1.0 : 0.0;
  s.step = s.angle = s.width = -1.0;
  s.materials = nullptr;
  s.material_count = 0;
  s.ol_level = 0;
  s.ol_resolution = 0;
  s.cache_bytes = 0;
  return s;
}

void check_lsystem_settings(const plm_lsystem_settings& s, const std::string& label) {
  check_placement(s.matrix, label);
  const double v[3] = {s.step, s.angle, s.width};
  const char* names[3] = {"step", "angle", "width"};
  for (int i = 0; i < 3; ++i)
    if (!std::isfinite(v[i])) fail(PLM_ERROR_INVALID_ARGUMENT, label, ": ", names[i], " is not finite (< 0: the rules')");
  if (s.material_count && !s.materials)
    fail(PLM_ERROR_INVALID_ARGUMENT, label, ": materials is NULL but material_count is ", s.material_count);
  if (s.ol_resolution > ol::kMaxOlResolution)
    fail(PLM_ERROR_INVALID_ARGUMENT, label, ": ol_resolution ", s.ol_resolution, " exceeds ", ol::kMaxOlResolution,
         " bins per side (0 = 16)");
  if (s.ol_level >= uint32_t(kMaxGraphLevels))
    fail(PLM_ERROR_INVALID_ARGUMENT, label, ": ol_level ", s.ol_level, " exceeds the graph's ", kMaxGraphLevels - 1,
         " levels");
  if (s.depth > uint32_t(kMaxGraphLevels) - 1)
    fail(PLM_ERROR_INVALID_ARGUMENT, label, ": depth ", s.depth, " needs ", uint64_t(s.depth) + 1,
         " traversal levels, over the limit of ", kMaxGraphLevels);
}

LSystemObject::LSystemObject(const std::string& name, const char* rules, const plm_lsystem_settings& s,
                             size_t scene_materials)
    : name_(name) {
  const std::string label = "L-system '" + name + "'";
  check_lsystem_settings(s, label);
  const uint32_t limit = uint32_t(std::max<size_t>(1, scene_materials));
  for (uint32_t i = 0; i < s.material_count; ++i)
    if (s.materials[i] >= limit)
      fail(PLM_ERROR_INVALID_ARGUMENT, label, ": materials[", i, "] = ", s.materials[i], " does not exist (",
           scene_materials, " materials; add materials first)");
  materials_.assign(s.materials, s.materials + s.material_count);
  if (materials_.empty()) materials_.push_back(0);
  ol_level_ = s.ol_level;
  ol_resolution_ = s.ol_resolution ? s.ol_resolution : 16;
  to_world_ = Affine3d::from_array(s.matrix);
  to_local_ = inverse(to_world_);
  graph_ = build_graph(rules, s, label);
  // World bounds: the graph's exact box of the placed primitives (tight when rotated).
  lo_ = graph_->world_bounds_lo();
  hi_ = graph_->world_bounds_hi();
  if (lo_.x <= hi_.x && lo_.y <= hi_.y && lo_.z <= hi_.z) {
    if (!is_finite(lo_) || !is_finite(hi_) || max_abs_component(lo_) > 1e12 || max_abs_component(hi_) > 1e12)
      fail(PLM_ERROR_INVALID_ARGUMENT, label, ": the placed object reaches beyond the engine's range of +-1e12 m");
  }
}

uint32_t LSystemObject::scene_material(int32_t turtle) const {
  const size_t i = std::min(size_t(std::max(turtle, 0)), materials_.size() - 1);
  return materials_[i];
}

bool LSystemObject::first_hit(Vec3d o, Vec3d d, double tnear, double tfar, GraphHit* hit) const {
  if (!graph_->first_hit(to_local_.point(o), to_local_.vector(d), tnear, tfar, hit)) return false;
  hit->n = normalize(to_world_.vector(hit->n));
  return true;
}

bool LSystemObject::occluded(Vec3d o, Vec3d d, double tnear, double tfar) const {
  return graph_->occluded(to_local_.point(o), to_local_.vector(d), tnear, tfar);
}

uint64_t LSystemObject::stub_key(const GraphHit& hit) const {
  return ol_level_ ? graph_->ancestor_key(hit, int(ol_level_)) : 0;
}

OlAreas LSystemObject::estimate_areas(const ol::OctGrid& grid, std::vector<std::string>& warnings) const {
  OlAreas out;
  const FlattenResult flat = graph_->flatten(kMaxAreaPrimitives, int(ol_level_));
  const size_t n = flat.primitives.size();
  out.primitives = n;
  out.truncated = flat.truncated;
  if (flat.truncated) {
    const uint64_t total = graph_->stats().flattened_primitives;
    out.scale = double(std::max<uint64_t>(total, n)) / double(std::max<size_t>(n, 1));
    warnings.push_back("L-system '" + name_ + "': has about " + std::to_string(total) +
                       " primitives; OL areas are estimated from the first " + std::to_string(n) +
                       " and scaled by " + std::to_string(out.scale));
  }
  const size_t bins = grid.bins();
  // Stub keys in first-appearance order, so sums are reduced in a fixed order.
  std::unordered_map<uint64_t, uint32_t> stub_index;
  std::vector<uint32_t> prim_stub(n, 0);
  std::vector<uint64_t> stub_keys;
  for (size_t i = 0; i < n; ++i) {
    const uint64_t k = ol_level_ ? flat.keys[i] : 0;
    auto it = stub_index.emplace(k, uint32_t(stub_keys.size())).first;
    if (it->second == stub_keys.size()) stub_keys.push_back(k);
    prim_stub[i] = it->second;
  }
  out.stub_instances = ol_level_ ? stub_keys.size() : 0;
  const size_t max_stubs = std::max<size_t>(1, kMaxStubBins / bins);
  const bool stubs = ol_level_ > 0 && stub_keys.size() <= max_stubs;
  if (ol_level_ > 0 && !stubs) {
    out.stubs_dropped = true;
    warnings.push_back("L-system '" + name_ + "': " + std::to_string(stub_keys.size()) + " instances at ol_level " +
                       std::to_string(ol_level_) + " exceed the " + std::to_string(max_stubs) + " stub OLs of " +
                       std::to_string(grid.resolution()) + "^2 bins that fit the memory limit; only the object's "
                       "root OL is kept (lower ol_level or ol_resolution)");
  }
  // Chunks of primitives, each summing into its own arrays; merged in chunk order.
  constexpr size_t kChunk = 8192;
  const size_t chunks = (n + kChunk - 1) / kChunk;
  struct ChunkSums {
    std::vector<double> area, var;
    std::unordered_map<uint32_t, std::vector<double>> stubs;
  };
  std::vector<ChunkSums> sums(chunks);
  auto world_desc = [&](size_t i, csg::PrimitiveDesc& desc) {
    const TurtlePrimitive& tp = flat.primitives[i];
    desc.shape = csg_shape(tp.shape);
    const Affine3d local = Affine3d::from_array(tp.to_world);
    const Affine3d w = compose(to_world_, local);
    std::copy(w.m, w.m + 12, desc.to_world);
    return csg::check_primitive(desc).empty();  // false: degenerate, no area
  };
  // Total area first: faces get samples in proportion to their area.
  std::vector<double> chunk_area(chunks, 0.0);
  tbb::parallel_for(size_t(0), chunks, [&](size_t c) {
    for (size_t i = c * kChunk; i < std::min(n, (c + 1) * kChunk); ++i) {
      csg::PrimitiveDesc desc;
      if (!world_desc(i, desc)) continue;
      const csg::Primitive prim = csg::make_primitive(desc);
      for (int f = 0; f < csg::face_count(prim.shape); ++f)
        if (prim.area[f] > 0.0 && std::isfinite(prim.area[f])) chunk_area[c] += prim.area[f];
    }
  });
  double total_area = 0.0;
  for (const double a : chunk_area) total_area += a;
  tbb::parallel_for(size_t(0), chunks, [&](size_t c) {
    ChunkSums& cs = sums[c];
    cs.area.assign(bins, 0.0);
    cs.var.assign(bins, 0.0);
    std::vector<uint32_t> sample_bins;
    for (size_t i = c * kChunk; i < std::min(n, (c + 1) * kChunk); ++i) {
      csg::PrimitiveDesc desc;
      if (!world_desc(i, desc)) continue;
      const csg::Primitive prim = csg::make_primitive(desc);
      Rng rng(0x4152454173ull, i);
      std::vector<double>* stub = stubs ? &cs.stubs[prim_stub[i]] : nullptr;
      if (stub && stub->empty()) stub->assign(bins, 0.0);
      for (int f = 0; f < csg::face_count(prim.shape); ++f) {
        const double a = prim.area[f];
        if (!(a > 0.0) || !std::isfinite(a)) continue;
        const double share = double(kAreaSamplesTotal) * a / total_area;
        const size_t want = size_t(std::clamp(std::ceil(share), double(kAreaSamplesPerFace), double(kAreaSamplesTotal)));
        sample_bins.clear();
        for (size_t k = 0; k < want; ++k) {
          csg::FaceSample fs;
          if (!csg::sample_face(prim, f, rng, fs)) break;
          sample_bins.push_back(grid.bin(ol_normal(fs.n)));
        }
        const size_t got = sample_bins.size();
        if (got == 0) continue;
        std::sort(sample_bins.begin(), sample_bins.end());
        for (size_t k = 0; k < got;) {
          size_t e = k;
          while (e < got && sample_bins[e] == sample_bins[k]) ++e;
          const double p = double(e - k) / double(got);
          cs.area[sample_bins[k]] += a * p;
          cs.var[sample_bins[k]] += a * a * p * (1.0 - p) / double(got);
          if (stub) (*stub)[sample_bins[k]] += a * p;
          k = e;
        }
      }
    }
  });
  out.root.assign(bins, 0.0);
  out.root_variance.assign(bins, 0.0);
  for (const ChunkSums& cs : sums) {
    for (size_t b = 0; b < bins; ++b) {
      out.root[b] += cs.area[b] * out.scale;
      out.root_variance[b] += cs.var[b] * out.scale * out.scale;
    }
    for (const auto& [s, area] : cs.stubs) {
      std::vector<double>& dst = out.stubs[stub_keys[s]];
      if (dst.empty()) dst.assign(bins, 0.0);
      for (size_t b = 0; b < bins; ++b) dst[b] += area[b];
    }
  }
  return out;
}

FlattenResult flatten_lsystem(const char* rules, const plm_lsystem_settings& s, size_t max_primitives) {
  const std::string label = "L-system";
  check_lsystem_settings(s, label);
  const std::unique_ptr<Graph> graph = build_graph(rules, s, label);
  FlattenResult r = graph->flatten(max_primitives);
  const Affine3d place = Affine3d::from_array(s.matrix);
  for (TurtlePrimitive& p : r.primitives) {
    const Affine3d local = Affine3d::from_array(p.to_world);
    const Affine3d w = compose(place, local);
    std::copy(w.m, w.m + 12, p.to_world);
  }
  return r;
}

// ---- Embree ----

namespace {

void object_bounds(const RTCBoundsFunctionArguments* args) {
  const LSystemObject& obj = *static_cast<const LSystemObject*>(args->geometryUserPtr);
  const Vec3d lo = obj.bounds_lo(), hi = obj.bounds_hi();
  // Padded by a relative 1e-7 beyond float rounding: the box maps corners in double.
  const double pad = 1e-7 * std::max(max_abs_component(hi - lo), std::max(max_abs_component(lo), max_abs_component(hi)));
  write_bounds(lo, hi, pad, args->bounds_o);
}

}  // namespace

unsigned attach_lsystem(RTCDevice device, RTCScene scene, const LSystemObject& object) {
  return attach_user_geometry<object_bounds, intersect_n<LSystemObject>, occluded_n<LSystemObject>>(device, scene,
                                                                                                    &object);
}

}  // namespace plm::lsystem
