// The C API's bake settings (photonlm.h, plm_bake_settings) and the engine's
// (transport/plan/settings.h): the one place that reads the C struct for a bake.
#pragma once

#include "photonlm/photonlm.h"
#include "scene/scene.h"
#include "transport/plan/settings.h"

namespace plm {

// plm_bake_settings_default's values.
plm_bake_settings default_settings();

namespace api {

// The caller's settings as the engine's, decided for `scene` (BakeSettings::decide).
BakeSettings engine_settings(const plm_bake_settings& c, const Scene& scene);

// The engine's settings as a whole current C struct (plm_part_info).
plm_bake_settings c_settings(const BakeSettings& s);

}  // namespace api
}  // namespace plm
