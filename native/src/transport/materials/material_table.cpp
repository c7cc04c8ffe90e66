#include "transport/materials/material_table.h"

#include <cmath>

namespace plm {

Cauchy cauchy_fit(float ior_d, float abbe) {
  Cauchy c;
  c.a = ior_d;
  if (!(abbe > 0.0f)) return c;
  constexpr double kD = 0.5876, kF = 0.4861, kC = 0.6563;  // Fraunhofer d, F, C lines (micrometres)
  const double b = (double(ior_d) - 1.0) / (double(abbe) * (1.0 / (kF * kF) - 1.0 / (kC * kC)));
  c.b = float(b);
  c.a = float(double(ior_d) - b / (kD * kD));
  return c;
}

MaterialTable::MaterialTable(const Scene& scene) {
  materials_.resize(scene.materials.size());
  for (size_t m = 0; m < scene.materials.size(); ++m) {
    const Material& mat = scene.materials[m];
    MaterialLobes& e = materials_[m];
    e.first = uint32_t(lobes_.size());
    e.count = uint32_t(mat.lobes.size());
    bool all_transparent = !mat.lobes.empty();
    std::vector<uint32_t> layered;  // the material's SPECULAR lobes, by index into lobes_
    for (const Lobe& l : mat.lobes) {
      layer_of_.push_back(l.type == PLM_LOBE_SPECULAR ? uint32_t(layers_.size()) : 0u);
      if (l.type == PLM_LOBE_SPECULAR) {
        layered.push_back(uint32_t(lobes_.size()));
        layers_.push_back(bsdf::make_layer_table(bsdf::lobe_params(l)));
      }
      lobes_.push_back(bsdf::lobe_params(l));
      cauchy_.push_back(cauchy_fit(l.ior, l.abbe));
      if (l.abbe > 0.0f) e.dispersive = true;
      if (l.type == PLM_LOBE_TRANSPARENT) e.pass_tint += lobes_.back().tint;
      else all_transparent = false;
    }
    if (all_transparent) {
      e.passage = Passage::Transparent;
    } else if (mat.lobes.size() == 1 && mat.lobes[0].refracts() && lobes_.back().smooth && mat.lobes[0].abbe == 0.0f) {
      e.passage = Passage::Pane;
      e.pass_tint = lobes_.back().tint;
      e.pane_ior = mat.lobes[0].ior;
      e.pane_fresnel = mat.lobes[0].type == PLM_LOBE_GLASS;
    } else {
      e.pass_tint = {0, 0, 0};
    }
    if (!layered.empty()) {
      // 1 - the layers' weight-averaged albedo (one layer: 1 - A exactly).
      double weights = 0.0;
      for (uint32_t li : layered) weights += lobes_[li].tint.x;
      e.layer_scale = uint32_t(diffuse_scales_.size() / bsdf::kLayerNodes);
      double mean = 0.0;
      for (int j = 0; j < bsdf::kLayerNodes; ++j) {
        double a = 0.0;
        for (uint32_t li : layered) a += weights > 0.0 ? lobes_[li].tint.x / weights * layers_[layer_of_[li]].A[j] : 0.0;
        const float scale = float(std::fmin(std::fmax(1.0 - a, 0.0), 1.0));
        diffuse_scales_.push_back(scale);
        // Cosine-weighted mean, 2 integral scale(mu) mu dmu, by the midpoint of each node's share.
        const double mu = double(j) / (bsdf::kLayerNodes - 1);
        const double w = (j == 0 || j == bsdf::kLayerNodes - 1) ? 0.5 : 1.0;
        mean += 2.0 * w * scale * mu / (bsdf::kLayerNodes - 1);
      }
      e.layer_mean = float(std::fmax(mean, 1e-6));
    }
    float burley[bsdf::kLayerNodes];
    if (mat.diffuse_model == PLM_DIFFUSE_BURLEY) {
      e.burley = mat.diffuse_roughness;
      bsdf::make_burley_albedo(mat.diffuse_roughness, burley);
      e.burley_albedo = uint32_t(burley_albedos_.size() / bsdf::kLayerNodes);
      burley_albedos_.insert(burley_albedos_.end(), burley, burley + bsdf::kLayerNodes);
      any_burley_ = true;
    }
    if (e.burley >= 0.0f || e.layer_scale != MaterialLobes::kNoLayer) {
      e.view_scale = uint32_t(view_scales_.size() / bsdf::kLayerNodes);
      for (int j = 0; j < bsdf::kLayerNodes; ++j) {
        float v = e.layer_scale != MaterialLobes::kNoLayer ? diffuse_scales_[size_t(e.layer_scale) * bsdf::kLayerNodes + j]
                                                           : 1.0f;
        if (e.burley >= 0.0f) v *= burley[j] / burley[bsdf::kLayerNodes - 1];
        view_scales_.push_back(v);
      }
    }
    any_passage_ = any_passage_ || e.passage != Passage::Opaque;
    any_dispersion_ = any_dispersion_ || e.dispersive;
  }
}

}  // namespace plm
