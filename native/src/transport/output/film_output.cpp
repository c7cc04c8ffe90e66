#include "transport/output/film_output.h"

#include <tbb/enumerable_thread_specific.h>

#include <algorithm>
#include <cmath>

#include "lightmap/dilate.h"
#include "lightmap/object_seams.h"
#include "lightmap/stitch.h"
#include "transport/output/layers.h"

namespace plm {
namespace {

// A lightmap resolved from an OL: each covered texel shows the OL at its
// normal (bilinear over the bins), with that bin's error and hit count.
void resolve_ol(const ol::OrientationLightmap& map, const TexelAreas& areas, std::vector<float>& values,
                std::vector<float>& hits, std::vector<uint8_t>& filled) {
  for (size_t t = 0; t < areas.area.size(); ++t) {
    if (!(areas.area[t] > 0.0)) continue;
    const Vec3 n = areas.normal[t];
    filled[t] = 1;
    if (!map.finalized() || !(dot(n, n) > 0.0f)) continue;  // no photons, or no normal: black
    const Vec3 v = map.lookup(n);
    const uint32_t b = map.bin_of(n);
    for (int c = 0; c < 3; ++c) values[4 * t + c] = v[c];
    values[4 * t + 3] = float(map.radiosity_error(b));
    hits[t] = float(map.hits(b));
  }
}

// A carrier's lightmap: each covered texel averages the solid's sub-texels
// found at four points around its centre (a quarter texel out along the
// surface, then to the nearest point of the exact surface along the normal):
// a box filter over the texel's footprint, which resamples the solid's texels
// with less error and noise than one point. The search reaches 2% of the
// solid's size: the tessellation's distance from the exact surface (a
// 32-segment circle: 0.5% of its radius).
void transfer_csg(const Estimator& est, size_t c, uint64_t photons, const TexelAreas& areas,
                  std::vector<float>& values, std::vector<float>& hits, std::vector<uint8_t>& filled,
                  std::vector<std::string>& warnings, const Mesh& mesh) {
  const CsgView& cv = est.space.csg_views[c];
  const Vec3d size = cv.object->bounds_hi() - cv.object->bounds_lo();
  const double tolerance = 0.02 * std::max({size.x, size.y, size.z});
  uint32_t missed = 0;
  for (size_t t = 0; t < areas.area.size(); ++t) {
    if (!(areas.area[t] > 0.0)) continue;
    const Vec3 n = areas.normal[t];
    Vec3 tu, tv;
    make_frame(n, tu, tv);
    const float quarter = 0.25f * float(std::sqrt(areas.area[t] / std::max(double(areas.coverage[t]), 1e-3)));
    int64_t subs[4];
    int found = 0;
    for (int k = 0; k < 4; ++k) {
      const Vec3 p = areas.position[t] + tu * (k & 1 ? quarter : -quarter) + tv * (k & 2 ? quarter : -quarter);
      const int64_t sub = cv.lightmap->lookup(to_double(p), to_double(n), tolerance);
      if (sub < 0) continue;
      bool seen = false;
      for (int j = 0; j < found; ++j) seen = seen || subs[j] == sub;
      if (!seen) subs[found++] = sub;
    }
    if (found == 0) {
      ++missed;
      continue;  // filled by dilation from its neighbours
    }
    double sum3[3] = {0, 0, 0}, var = 0.0, hit_count = 0.0;
    for (int j = 0; j < found; ++j) {
      double v3[3];
      var += est.csg_texel(c, uint32_t(subs[j]), photons, v3);
      for (int ch = 0; ch < 3; ++ch) sum3[ch] += v3[ch];
      hit_count += est.acc.hits[cv.texel_offset + uint64_t(subs[j])];
      if (!est.acc.caustic.empty()) hit_count += est.acc.caustic.hits[cv.texel_offset + uint64_t(subs[j])];
    }
    for (int ch = 0; ch < 3; ++ch) values[4 * t + ch] = float(sum3[ch] / found);
    values[4 * t + 3] = float(std::sqrt(var) / found);  // the mean of `found` independent sub-texels
    hits[t] = float(hit_count);
    filled[t] = 1;
  }
  if (missed)
    warnings.push_back("mesh '" + mesh.name + "': " + std::to_string(missed) + " texels found no point of CSG solid '" +
                       cv.object->name() + "' within " + std::to_string(tolerance) +
                       " m (the mesh does not follow the solid there); they take their neighbours' values");
}

// A lightmap backed up by an OL (plm_scene_set_ol_group_backup): each
// texel's indirect part (its estimate minus its direct light) and the OL at
// its normal are combined by inverse variance, the OL's variance including its
// squared bias against the texel: the larger of the lightmap's mean of
// (texel - OL)^2 - both variances (unbiased for the mean squared bias) and the
// texel's own such difference where it exceeds two standard deviations.
void blend_backup(const ol::OrientationLightmap& map, const TexelAreas& areas, const DirectValues& direct,
                  size_t first_covered, std::vector<double>& value3, std::vector<double>& variance) {
  struct Parts {
    size_t t;
    double ind[3], var_ind, ol[3], var_ol, var_direct, direct[3], diff_sq;
  };
  std::vector<Parts> parts;
  size_t k = first_covered;
  double bias_sum = 0.0;
  for (size_t t = 0; t < areas.area.size(); ++t) {
    if (!(areas.area[t] > 0.0)) continue;
    Parts p{t, {0, 0, 0}, 0.0, {0, 0, 0}, 0.0, 0.0, {0, 0, 0}, 0.0};
    if (!direct.empty()) {
      for (int c = 0; c < 3; ++c) p.direct[c] = direct.value3[3 * k + c];
      p.var_direct = direct.variance[k++];
    }
    for (int c = 0; c < 3; ++c) p.ind[c] = value3[3 * t + c] - p.direct[c];
    p.var_ind = std::max(0.0, variance[t] - p.var_direct);
    const Vec3 n = areas.normal[t];
    if (!(dot(n, n) > 0.0f)) continue;  // no normal: the texel keeps its own estimate
    const Vec3 o = map.lookup(n);
    for (int c = 0; c < 3; ++c) p.ol[c] = o[c];
    const double e = map.radiosity_error(map.bin_of(n));
    p.var_ol = e * e;
    const double diff = (p.ind[0] + p.ind[1] + p.ind[2] - p.ol[0] - p.ol[1] - p.ol[2]) / 3.0;
    p.diff_sq = diff * diff;
    bias_sum += diff * diff - p.var_ind - p.var_ol;
    parts.push_back(p);
  }
  if (parts.empty()) return;
  const double bias_sq = std::max(0.0, bias_sum / double(parts.size()));
  for (const Parts& p : parts) {
    // The texel's own evidence of bias counts too: where it differs from the OL by
    // more than both noises explain, the OL is biased there (a corner, a box top
    // sharing the floor's normal), and the texel keeps more of its own estimate.
    const double noise = p.var_ind + p.var_ol;
    const double local = p.diff_sq > 4.0 * noise ? p.diff_sq - noise : 0.0;  // beyond 2 sigma: evidence
    const double var_o = p.var_ol + std::max(bias_sq, local);
    // Weights 1/var; a texel with no variance estimate (or an exact OL) keeps the better one alone.
    const double wt = p.var_ind > 0.0 ? 1.0 / p.var_ind : 1e300, wo = var_o > 0.0 ? 1.0 / var_o : 1e300;
    const double a = wt / (wt + wo);
    for (int c = 0; c < 3; ++c) value3[3 * p.t + c] = p.direct[c] + a * p.ind[c] + (1.0 - a) * p.ol[c];
    variance[p.t] = p.var_direct + a * a * p.var_ind + (1.0 - a) * (1.0 - a) * var_o;
  }
}

// Parts of mesh i's lightmap (its light-group layers, layer_texels, or its
// direction moments, direction_texels: 4 floats a texel, the last the part's
// error) dilated and stitched as the whole lightmap is: the same texels
// filled from the same neighbours, and seams solved with the whole's error as
// every part's weights, so that layers still add up to the whole.
// `stitched`: the whole after dilation and stitching (its error channel is
// the one the stitch weighed by). Into rgb (3 per texel) and, if given, error.
void write_parts(std::vector<std::vector<float>>& parts, const std::vector<uint8_t>& covered,
                 const std::vector<float>& stitched, uint32_t dilation, const std::vector<SeamEdge>* seams,
                 const LightmapImage& img, std::vector<std::vector<float>>& rgb,
                 std::vector<std::vector<float>>* error) {
  const size_t n = covered.size();
  rgb.resize(parts.size());
  if (error) error->resize(parts.size());
  for (size_t l = 0; l < parts.size(); ++l) {
    std::vector<float>& v = parts[l];
    std::vector<uint8_t> filled = covered;
    dilate(v, 4, filled, img.width, img.height, dilation);
    std::vector<float> e(n);
    for (size_t t = 0; t < n; ++t) e[t] = v[4 * t + 3], v[4 * t + 3] = stitched[4 * t + 3];
    if (seams) stitch_seams(*seams, covered, v, 4, img.width, img.height);
    rgb[l].resize(3 * n);
    for (size_t t = 0; t < n; ++t)
      for (int c = 0; c < 3; ++c) rgb[l][3 * t + c] = v[4 * t + c];
    if (error) (*error)[l] = std::move(e);
  }
}

}  // namespace

void sh_band(const LightmapImage& img, uint32_t band, float* rgb) {
  const size_t n = size_t(img.width) * img.height;
  if (band == 0) {  // V / 2 = kShEval0 L0
    for (size_t f = 0; f < 3 * n; ++f) rgb[f] = float(img.rgb[f] / (2.0 * kShEval0));
    return;
  }
  const std::vector<float>& d = img.direction_rgb[band == 1 ? 1 : band == 2 ? 2 : 0];  // y, z, x
  for (size_t f = 0; f < 3 * n; ++f) rgb[f] = float(d[f] / kShEval1);
}

void write_lightmaps(tbb::task_arena& arena, const Scene& scene, const Estimator& est, uint64_t photons,
                     const std::vector<ol::OrientationLightmap>& ols, Estimate& last, uint32_t dilation,
                     std::vector<LightmapImage>& images, std::vector<std::string>& warnings) {
  images.resize(scene.meshes.size());
  const std::vector<TexelAreas>& areas = est.space.areas;
  const SceneSeams seams = find_scene_seams(scene);
  // Meshes in parallel (for_lightmaps), each with its own warnings, joined in order.
  std::vector<std::vector<std::string>> mesh_warnings(scene.meshes.size());
  tbb::enumerable_thread_specific<EstimateBuffers> buffers;
  auto texels = [&](size_t i) { return size_t(scene.meshes[i].lightmap_width) * scene.meshes[i].lightmap_height; };
  arena.execute([&] {
    for_lightmaps(scene.meshes.size(), texels, [&](size_t i) {
      const Mesh& mesh = scene.meshes[i];
      if (!mesh.has_lightmap()) return;
      LightmapImage& img = images[i];
      img.width = mesh.lightmap_width;
      img.height = mesh.lightmap_height;
      const size_t n = size_t(img.width) * img.height;
      std::vector<float> values(4 * n, 0.0f);  // R, G, B, error: dilated together
      std::vector<uint8_t> filled(n, 0);
      img.hits.assign(n, 0.0f);
      img.coverage = areas[i].coverage;
      const bool backed_up = mesh.ol_group >= 0 && scene.ol_groups[size_t(mesh.ol_group)].backup;
      if (mesh.ol_group >= 0 && !backed_up) {
        resolve_ol(ols[size_t(mesh.ol_group)], areas[i], values, img.hits, filled);
      } else if (mesh.csg_carrier >= 0) {
        transfer_csg(est, size_t(mesh.csg_carrier), photons, areas[i], values, img.hits, filled, mesh_warnings[i],
                     mesh);
      } else {
        if (backed_up && ols[size_t(mesh.ol_group)].finalized()) {
          EstimateBuffers& b = buffers.local();
          est.texels(i, photons, b);
          blend_backup(ols[size_t(mesh.ol_group)], areas[i], est.direct, est.space.covered_begin[i], b.value3,
                       b.variance);
          for (size_t t = 0; t < n; ++t)
            if (areas[i].area[t] > 0.0) store_texel(b.value3, b.variance, t, values.data());
        } else {
          values.swap(last.values[i]);  // the final estimate's texels
        }
        for (size_t t = 0; t < n; ++t) {
          if (!(areas[i].area[t] > 0.0)) continue;
          img.hits[t] = float(est.acc.hits[est.space.views[i].texel_offset + t]);
          if (!est.acc.caustic.empty())
            img.hits[t] += float(est.acc.caustic.hits[est.space.views[i].texel_offset + t]);
          filled[t] = 1;
        }
      }
      const std::vector<uint8_t> covered = filled;
      const std::vector<float> undilated = est.acc.slots() ? values : std::vector<float>();
      dilate(values, 4, filled, img.width, img.height, dilation);
      if (!seams.joint[i]) stitch_seams(seams.within[i], covered, values, 4, img.width, img.height);
      const std::vector<SeamEdge>* within = seams.joint[i] ? nullptr : &seams.within[i];
      if (est.acc.split.layers) {
        std::vector<std::vector<float>> parts;
        layer_texels(est, i, photons, undilated, parts);
        write_parts(parts, covered, values, dilation, within, img, img.layer_rgb, &img.layer_error);
      }
      if (est.acc.split.directional) {
        std::vector<std::vector<float>> parts;
        direction_texels(est, i, photons, undilated, parts);
        write_parts(parts, covered, values, dilation, within, img, img.direction_rgb, nullptr);
      }
      img.rgb.resize(3 * n);
      img.error.resize(n);
      for (size_t t = 0; t < n; ++t) {
        for (int c = 0; c < 3; ++c) img.rgb[3 * t + c] = values[4 * t + c];
        img.error[t] = values[4 * t + 3];
      }
    });
  });
  for (std::vector<std::string>& w : mesh_warnings) warnings.insert(warnings.end(), w.begin(), w.end());
  if (seams.between.empty()) return;
  // Meshes with seams between them: stitched together (their covered texels
  // are those with area, as they hold their own texels).
  std::vector<std::vector<uint8_t>> covered(images.size());
  std::vector<SeamImage> view(images.size());
  for (size_t i = 0; i < images.size(); ++i) {
    if (!seams.joint[i]) continue;
    for (double a : areas[i].area) covered[i].push_back(a > 0.0);
    view[i] = {images[i].rgb.data(), 3, images[i].error.data(), 1, covered[i].data(), images[i].width, images[i].height};
  }
  arena.execute([&] { stitch_scene_seams(seams, view); });
  // Each light-group layer and direction moment stitched as the whole was, weighed by the whole's error.
  auto stitch_parts = [&](uint32_t count, auto part_of) {
    for (uint32_t l = 0; l < count; ++l) {
      std::vector<SeamImage> part_view = view;
      std::vector<std::vector<float>> spare(images.size());  // a mesh without parts: its colours untouched
      for (size_t i = 0; i < images.size(); ++i) {
        if (!seams.joint[i]) continue;
        std::vector<std::vector<float>>& parts = part_of(images[i]);
        if (parts.size() <= l) spare[i] = images[i].rgb;
        part_view[i].colour = parts.size() > l ? parts[l].data() : spare[i].data();
      }
      arena.execute([&] { stitch_scene_seams(seams, part_view); });
    }
  };
  stitch_parts(est.acc.split.layers, [](LightmapImage& img) -> std::vector<std::vector<float>>& { return img.layer_rgb; });
  if (est.acc.split.directional)
    stitch_parts(3, [](LightmapImage& img) -> std::vector<std::vector<float>>& { return img.direction_rgb; });
}

}  // namespace plm
