/*
 * photonlm: photon-lightmap global illumination baker, C API (plain C99).
 * Citations such as [Thesis §3.5.2] here and in the sources refer to the
 * references of docs/design/references.md ([Thesis]: A. Wilkie, Photon Tracing for
 * Complex Environments, PhD thesis, TU Vienna, 2001).
 *
 * Conventions
 * - Every function that can fail returns a plm_status. On failure, a message
 *   saying what was wrong and where (mesh name, triangle or vertex index) is
 *   kept per thread and read with plm_last_error() on the same thread.
 * - Handles are opaque. Buffers are owned by the caller; the library copies
 *   what it keeps, so arrays may be freed right after a call returns.
 * - Units follow Blender/Cycles: metres, linear RGB, radiance in W m^-2 sr^-1.
 * - A lightmap texel holds irradiance / pi (diffuse lighting without albedo),
 *   exactly what Cycles bakes with type DIFFUSE, DIRECT+INDIRECT, no COLOR.
 * - Lightmap rows are in UV order: row 0 covers v in [0, 1/height), i.e.
 *   bottom row first (the order of Blender's Image.pixels). EXR files are
 *   written top row first, as image files are.
 * - Structs the caller allocates start with their size (see "Struct sizes").
 */
#ifndef PHOTONLM_PHOTONLM_H
#define PHOTONLM_PHOTONLM_H

#include <stddef.h>
#include <stdint.h>

#if defined(_WIN32)
#  if defined(PHOTONLM_BUILDING)
#    define PLM_API __declspec(dllexport)
#  else
#    define PLM_API __declspec(dllimport)
#  endif
#else
#  define PLM_API __attribute__((visibility("default")))
#endif

#ifdef __cplusplus
extern "C" {
#endif

#define PLM_VERSION_MAJOR 0
#define PLM_VERSION_MINOR 1
#define PLM_VERSION_PATCH 0

typedef enum plm_status {
  PLM_OK = 0,
  PLM_ERROR_INVALID_ARGUMENT = 1, /* a NULL pointer, a bad size, NaN/Inf... */
  PLM_ERROR_INVALID_SCENE = 2,    /* the scene cannot be baked as it is */
  PLM_ERROR_OUT_OF_MEMORY = 3,
  PLM_ERROR_IO = 4,               /* a file could not be written */
  PLM_ERROR_CANCELLED = 5,        /* the progress callback asked to stop */
  PLM_ERROR_INTERNAL = 6,         /* a bug: please report the message */
  PLM_ERROR_STRUCT_SIZE = 7       /* a struct's struct_size is not a layout this library knows */
} plm_status;

typedef struct plm_scene plm_scene;   /* what the user described */
typedef struct plm_result plm_result; /* the lightmaps of one bake */

/* Library version as "major.minor.patch". */
PLM_API const char* plm_version(void);
/* Short name of a status code ("PLM_ERROR_IO"). */
PLM_API const char* plm_status_string(plm_status status);
/* Message of the last failed call on this thread ("" if none). */
PLM_API const char* plm_last_error(void);

/* ---- Struct sizes ----------------------------------------------------------
 *
 * Every struct the caller allocates and the library reads or writes
 * (plm_lobe, plm_light, plm_csg_primitive, plm_csg_node, plm_bake_settings,
 * plm_bake_stats, plm_ol_stats, plm_lsystem_settings, plm_lsystem_stats)
 * starts with `uint32_t struct_size`: sizeof the struct as the caller's
 * header declares it. The *_default functions set it with the rest; a caller
 * that fills a struct itself (the stats structs, plm_csg_primitive and
 * plm_csg_node, which have no *_default) sets it to sizeof. Fields are only
 * ever added at the end of a struct, so an older header's struct is a prefix
 * of the current one: the library reads only the first struct_size bytes
 * (the fields past them take their defaults) and writes only the first
 * struct_size bytes (the rest of the caller's memory is left alone), and it
 * never changes struct_size. A size that is not one of the struct's layouts
 * (zero, garbage, below the oldest, above the current or between two) is
 * refused with PLM_ERROR_STRUCT_SIZE and a message naming the function, the
 * struct, the size given and the current size. The layouts the library
 * knows are the current one of each struct and these older ones:
 *   plm_bake_settings  up to filter_radius (no texel_value, sampler: their
 *                      defaults, PLM_TEXEL_CYCLES and PLM_SAMPLER_DEFAULT),
 *                      and up to sampler (no directional: 0)
 *   plm_bake_stats     up to error_p95 (no error_above, memory_estimate)
 *   plm_lobe           up to abbe (no weight: 1)
 * Arrays of structs (the primitives and nodes of plm_scene_add_csg) carry
 * the size in every element: the first element's struct_size is the array's
 * stride, and every element must carry the same one. */

/* ---- Scene --------------------------------------------------------------- */

PLM_API plm_status plm_scene_create(plm_scene** out_scene);
PLM_API void plm_scene_release(plm_scene* scene); /* NULL is fine */

/* A Lambertian material. albedo in [0, 1] per channel (values above 1 are an
 * error: they create energy); emission is radiance (Cycles: colour x strength),
 * emitted from both sides of the surface as Cycles does. name may be NULL. */
PLM_API plm_status plm_scene_add_material(plm_scene* scene, const char* name,
                                          const float albedo[3], const float emission[3],
                                          uint32_t* out_material_id);

/* Specular lobes: glass, mirrors, metal (docs/design/materials.md "Materials"). A
 * material is its diffuse part (plm_scene_add_material's albedo) plus the
 * lobes added here, in the order given, as Cycles' shader nodes sum their
 * closures: the add-on flattens Principled BSDF, Glass, Glossy, Refraction and
 * Transparent BSDFs and Mix / Add Shaders with constant factors into one
 * diffuse albedo and a list of lobes. A lobe reflects or transmits
 * `weight` x its reflectance, where the reflectance is
 *   PLM_LOBE_GLOSSY       `color` at every angle: GGX reflection (Glossy BSDF)
 *   PLM_LOBE_FRESNEL      `color` at normal incidence rising to 1 at grazing
 *                         as a dielectric of `ior` does: color + (1 - color)
 *                         (F(ior, cos) - F0) / (1 - F0), F exact Fresnel at the
 *                         microfacet, F0 = F(ior, 1): GGX reflection (Principled
 *                         BSDF's specular and metallic layer, color = its F0,
 *                         ior from its Specular; its clearcoat, F0 = 0.04)
 *   PLM_LOBE_GLASS        `color` x exact Fresnel reflection plus `color` x
 *                         the transmitted rest, refracted by `ior` (Glass BSDF,
 *                         Principled transmission)
 *   PLM_LOBE_REFRACTION   `color`, refracted only, no Fresnel term (Refraction
 *                         BSDF; under total internal reflection nothing)
 *   PLM_LOBE_TRANSPARENT  `color`, straight through (Transparent BSDF, alpha)
 *   PLM_LOBE_SPECULAR     the dielectric specular layer of Blender 4's
 *                         Principled BSDF: `color` (its F0 x Specular Tint)
 *                         rising to 1 at grazing along the curve of a
 *                         dielectric of `ior` as FRESNEL, GGX with
 *                         height-correlated masking and multiple-scattering
 *                         energy compensation (Cycles 4's Multiscatter GGX);
 *                         the material's diffuse part lies below it and is
 *                         scaled by 1 - A(cos), A the layer's directional
 *                         albedo (largest channel) towards where the light
 *                         leaves. With several SPECULAR lobes the diffuse part
 *                         is scaled by one minus their weight-averaged A.
 * Mix factors go into `weight` or `color` alike, except for FRESNEL, whose
 * curve rises to `weight` at grazing (`color` is its F0). roughness is
 * Blender's in [0, 1] (GGX alpha = roughness^2; 0 is a perfect mirror or
 * pane); ior > 0 relates the front side's medium (outside) to the back's
 * (used by FRESNEL, GLASS, REFRACTION); abbe > 0 gives GLASS and REFRACTION
 * lobes dispersion (Abbe number V_d, ior is then the index at 587.6 nm;
 * other types must leave it 0). color and weight are in [0, 1], and per
 * channel the diffuse albedo plus weight x color of every lobe but the
 * FRESNEL and SPECULAR ones must not exceed 1 (Cycles adds those layers on top
 * of the diffuse part). At most 8 lobes a material. Photons follow the lobes; the
 * lightmap still holds irradiance / pi of the surface (what its diffuse part
 * reflects, over its albedo). Errors name the material, the lobe and the bad
 * field. */
typedef enum plm_lobe_type {
  PLM_LOBE_GLOSSY = 0,
  PLM_LOBE_FRESNEL = 1,
  PLM_LOBE_GLASS = 2,
  PLM_LOBE_REFRACTION = 3,
  PLM_LOBE_TRANSPARENT = 4,
  PLM_LOBE_SPECULAR = 5
} plm_lobe_type;

typedef struct plm_lobe {
  uint32_t struct_size; /* sizeof(plm_lobe): see "Struct sizes" */
  int32_t type;    /* plm_lobe_type */
  float color[3];  /* linear RGB tint (FRESNEL: F0) */
  float roughness; /* 0..1, Blender's */
  float ior;       /* FRESNEL, GLASS, REFRACTION */
  float abbe;      /* GLASS, REFRACTION: 0 = no dispersion */
  float weight;    /* 0..1, the lobe's mix factor */
} plm_lobe;

/* Fills a lobe with defaults for its type: struct_size, white, weight 1,
 * roughness 0, ior 1.5 (1.45 for GLASS and REFRACTION, Blender's), no
 * dispersion. */
PLM_API void plm_lobe_default(plm_lobe* lobe, plm_lobe_type type);
/* Appends a lobe to a material (at most 8 a material). */
PLM_API plm_status plm_scene_add_material_lobe(plm_scene* scene, uint32_t material_id, const plm_lobe* lobe);

/* The diffuse part's scattering model (docs/design/cycles-versions.md "Cycles versions").
 *   PLM_DIFFUSE_LAMBERT  (default) Lambert: the Diffuse BSDF, Blender 4's
 *                        Principled BSDF
 *   PLM_DIFFUSE_BURLEY   Blender 3.x's Principled BSDF diffuse (Cycles 3.4
 *                        bsdf_principled_diffuse.h, Burley 2015): albedo / pi x
 *                        (1 - FL / 2)(1 - FV / 2) + R (FL + FV + FL FV (R - 1)),
 *                        F = (1 - cos)^5 at the light's (L) and the viewer's
 *                        (V) side, R = roughness (1 + L.V); roughness in [0, 1]
 *                        (the Principled BSDF's Roughness)
 * A Burley surface reflects light by that law, and its lightmap holds what
 * Cycles 3.4 bakes for it (DIFFUSE, no COLOR: the viewer along the normal),
 * each arriving direction weighted by 1 - FL / 2 + R FL, which is
 * irradiance / pi only where light arrives steeply. Errors: a bad model, a
 * roughness outside [0, 1], named with the material. */
typedef enum plm_diffuse_model { PLM_DIFFUSE_LAMBERT = 0, PLM_DIFFUSE_BURLEY = 1 } plm_diffuse_model;
PLM_API plm_status plm_scene_set_material_diffuse(plm_scene* scene, uint32_t material_id, int32_t model,
                                                  float roughness);

/* Image textures on materials (docs/design/materials.md "Textures").
 *   PLM_TEXTURE_ALBEDO    albedo = image x the material's albedo
 *   PLM_TEXTURE_EMISSION  emitted radiance = image x the material's emission
 * (multiplied, so pass albedo 1 1 1 for "the image replaces the colour", as
 * Blender's Image node into Base Color does; pass the strength as the
 * emission). Looked up at the point's texture UV (plm_scene_set_mesh_texture_uv)
 * with bilinear filtering on the full-resolution image and repeat wrapping,
 * like Cycles' Linear / Repeat Image node. Colour: flags
 * PLM_TEXTURE_COLOR_AUTO = 0 treats 8/16-bit integer images as sRGB (decoded
 * to linear, Blender's default) and float images (EXR, HDR) as linear;
 * PLM_TEXTURE_COLOR_LINEAR (Blender "Non-Color"/"Linear") or
 * PLM_TEXTURE_COLOR_SRGB force one; 8-bit sRGB images are filtered encoded and
 * decoded after the lookup, as Cycles does. Albedo images are clamped to
 * [0, 1]. The images are read into memory when the bake starts (as float
 * RGB: 12 bytes a pixel), so the files must stay until plm_bake begins.
 * Surfaces without texture UVs (a mesh without them, CSG solids, L-systems)
 * use the image's mean colour (a mesh gets a warning at bake time).
 * Emission textures: light leaves each point with the texture's colour there
 * (emitters are chosen by their mean over each triangle). slot is a
 * plm_texture_slot; path NULL or "" removes the texture. Errors: a bad slot,
 * a missing or unreadable file, named with the material. */
typedef enum plm_texture_slot { PLM_TEXTURE_ALBEDO = 0, PLM_TEXTURE_EMISSION = 1 } plm_texture_slot;
#define PLM_TEXTURE_COLOR_AUTO 0u
#define PLM_TEXTURE_COLOR_LINEAR 1u
#define PLM_TEXTURE_COLOR_SRGB 2u
PLM_API plm_status plm_scene_set_material_texture(plm_scene* scene, uint32_t material_id, int32_t slot,
                                                  const char* path, uint32_t flags);

/* Texture UVs of a mesh: triangle_count * 3 * 2 floats, the (u, v) of each
 * corner (face-varying, like lightmap_uv; any UV map, (0, 0) = the image's
 * bottom-left corner as in Blender). NULL removes them. Errors name the mesh
 * and the first non-finite value. */
PLM_API plm_status plm_scene_set_mesh_texture_uv(plm_scene* scene, uint32_t mesh_id, const float* uv);

/* Shading normals of a mesh (smooth shading, custom split normals):
 * triangle_count * 3 * 3 floats, the normal of each corner in world space
 * (any length; normalised by the engine). A corner given (0, 0, 0) shades
 * with its triangle's geometric normal, as a flat-shaded face does. Texels
 * are lit as Cycles bakes them: the cosine of each light's direction is taken
 * with the interpolated normal, and light from below the triangle's own
 * plane does not count. NULL (or normals that all equal the geometric ones)
 * leaves the mesh flat. Errors name the mesh, triangle and corner of the
 * first non-finite value. */
PLM_API plm_status plm_scene_set_mesh_normals(plm_scene* scene, uint32_t mesh_id, const float* normals);

/* Smooth shading without given normals (smooth != 0): each corner takes its
 * vertex's normal, the mean of the normals of the triangles around the vertex
 * weighted by their angle there, as Blender computes the normals of smooth
 * faces; for subdivision meshes (plm_scene_add_subdiv_mesh) those of the
 * refined mesh. smooth = 0 removes shading normals. */
PLM_API plm_status plm_scene_set_mesh_smooth(plm_scene* scene, uint32_t mesh_id, int smooth);

/* A triangle mesh in world space.
 *   positions      vertex_count * 3 floats (x, y, z)
 *   indices        triangle_count * 3 vertex indices
 *   lightmap_uv    triangle_count * 3 * 2 floats: the (u, v) of each corner
 *                  (face-varying, like Blender loops). May be NULL only when
 *                  the mesh has no lightmap (width = height = 0).
 *   material_ids   triangle_count material ids (materials must be added
 *                  first), or NULL for material 0 (a grey 0.8 material if
 *                  the scene has none).
 *   lightmap_width/height  texels; 0 x 0 means the mesh is geometry only
 *                  (it blocks and reflects light but gets no lightmap).
 * Errors name the mesh and the first bad vertex/triangle index. Degenerate
 * triangles (zero area) are legal: they are skipped and reported as a warning
 * on the bake result. */
PLM_API plm_status plm_scene_add_mesh(plm_scene* scene, const char* name,
                                      const float* positions, uint32_t vertex_count,
                                      const uint32_t* indices, uint32_t triangle_count,
                                      const float* lightmap_uv, const uint32_t* material_ids,
                                      uint32_t lightmap_width, uint32_t lightmap_height,
                                      uint32_t* out_mesh_id);

/* A Catmull-Clark subdivision surface given by its polygon cage in world
 * space. The engine refines it with OpenSubdiv as Blender 3.4's Subdivision
 * Surface modifier does with its defaults (limit surface on, boundary smooth
 * ALL, UV smooth PRESERVE_BOUNDARIES, creases on) and splits each refined quad
 * into two triangles. The id is an ordinary mesh id (lightmaps, OL groups and
 * results work as for plm_scene_add_mesh).
 *   positions       vertex_count * 3 floats
 *   face_sizes      face_count corner counts (each >= 3; n-gons are fine)
 *   face_indices    sum(face_sizes) vertex indices, face after face
 *   lightmap_uv     sum(face_sizes) * 2 floats, (u, v) per face corner, or
 *                   NULL when the mesh has no lightmap. Corners of one vertex
 *                   whose UVs agree within 1e-4 are smoothed together; the
 *                   others form UV seams, kept linear like island boundaries.
 *   material_ids    face_count ids, or NULL for material 0
 *   crease_edges    crease_count pairs of vertex indices, each an edge of the cage
 *   crease_weights  crease_count Blender edge creases in [0, 1]
 *   level           1..10; the refined mesh has 2 * sum(face_sizes) * 4^(level-1)
 *                   triangles, and more than 2^25 is an error.
 * Errors name the mesh and the first bad vertex, face, corner or crease. The
 * cage is checked (OpenSubdiv's own topology checks included) and copied here;
 * the refinement itself waits for plm_scene_refine_subdiv_meshes or the bake,
 * which refine all waiting cages together, in parallel. */
PLM_API plm_status plm_scene_add_subdiv_mesh(plm_scene* scene, const char* name,
                                             const float* positions, uint32_t vertex_count,
                                             const uint32_t* face_sizes, uint32_t face_count,
                                             const uint32_t* face_indices, const float* lightmap_uv,
                                             const uint32_t* material_ids, const uint32_t* crease_edges,
                                             const float* crease_weights, uint32_t crease_count,
                                             uint32_t level, uint32_t lightmap_width,
                                             uint32_t lightmap_height, uint32_t* out_mesh_id);

/* Refines every cage added by plm_scene_add_subdiv_mesh since the last call, in
 * parallel on thread_count threads (0 = all cores); the result does not depend
 * on the threads. The bakes call it themselves; a host calls it to have the
 * work done (and timed) where it chooses. A cage accepted by the add call fails
 * here only for want of memory; the error names the mesh (the lowest id among
 * those that failed), and every later call and bake fails with it again. */
PLM_API plm_status plm_scene_refine_subdiv_meshes(plm_scene* scene, uint32_t thread_count);

/* The refinement plm_scene_add_subdiv_mesh makes, returned to the caller (to
 * check it against Blender, or to preview it). Same cage arguments (lightmap_uv
 * may be NULL). Writes *out_vertex_count and *out_triangle_count; when the
 * buffers are non-NULL and large enough (vertex_capacity vertices,
 * triangle_capacity triangles) also fills out_positions (3 per vertex),
 * out_indices (3 per triangle) and out_uv (6 per triangle, only with
 * lightmap_uv), else PLM_ERROR_INVALID_ARGUMENT names the sizes needed. */
PLM_API plm_status plm_subdiv_refine(const float* positions, uint32_t vertex_count, const uint32_t* face_sizes,
                                     uint32_t face_count, const uint32_t* face_indices,
                                     const float* lightmap_uv, const uint32_t* crease_edges,
                                     const float* crease_weights, uint32_t crease_count, uint32_t level,
                                     float* out_positions, uint32_t vertex_capacity, uint32_t* out_indices,
                                     float* out_uv, uint32_t triangle_capacity, uint32_t* out_vertex_count,
                                     uint32_t* out_triangle_count);

typedef enum plm_light_type {
  PLM_LIGHT_POINT = 0,
  PLM_LIGHT_SPOT = 1,
  PLM_LIGHT_SUN = 2,
  PLM_LIGHT_AREA_RECT = 3, /* Blender area light, shape SQUARE or RECTANGLE */
  PLM_LIGHT_AREA_DISK = 4, /* Blender area light, shape DISK or ELLIPSE */
  /* Not a light: a rectangle (size_x x size_y, the matrix as for AREA_RECT,
   * local -Z pointing into the interior) in an opening through which sun and
   * sky light enter, as Cycles' portal lights. Sun and world photons and the
   * sky's direct light are then sampled mostly through the portals, the rest
   * as without them, so the result stays unbiased (light entering elsewhere
   * is still found, only more slowly); colour and power are ignored. */
  PLM_LIGHT_PORTAL = 5
} plm_light_type;

/* Whose conventions the scene's lights follow (docs/design/cycles-versions.md "Cycles
 * versions"): the Cycles of the Blender that made the scene.
 *   PLM_CONVENTIONS_CYCLES_3_4  (default) Blender 3.x: an area light of power P
 *                               and area A has radiance P / (4 A); a spot's
 *                               intensity in its cone is P / (4 pi) x
 *                               cos(angle from the axis), smoothstepped over
 *                               the blend
 *   PLM_CONVENTIONS_CYCLES_4    Blender 4.0 to 5.2: area radiance P / (pi A)
 *                               (all of P leaves the light); a spot's
 *                               intensity is P / (4 pi) x the smoothstep alone
 * Point and sun lights, emissive surfaces and the world are the same in both.
 * Materials say what they are by their lobes (a Blender 4 Principled BSDF's
 * layer is PLM_LOBE_SPECULAR whatever the conventions). Set it before the
 * bake; it may be set again, the last value counts. */
typedef enum plm_conventions {
  PLM_CONVENTIONS_CYCLES_3_4 = 0,
  PLM_CONVENTIONS_CYCLES_4 = 1
} plm_conventions;

PLM_API plm_status plm_scene_set_conventions(plm_scene* scene, int32_t conventions);
PLM_API plm_status plm_scene_get_conventions(const plm_scene* scene, int32_t* out_conventions);

/* A light, described as Blender describes it. The light's frame is the
 * object-to-world matrix (row-major, translation in the last column); lights
 * shine along their local -Z axis. Scale in the matrix scales area lights. */
typedef struct plm_light {
  uint32_t struct_size;  /* sizeof(plm_light): see "Struct sizes" */
  int32_t type;          /* plm_light_type */
  float color[3];        /* linear RGB */
  float power;           /* W for point, spot, area; irradiance W/m^2 for sun */
  float matrix[16];      /* object to world, row-major */
  float radius;          /* point/spot: Blender shadow_soft_size (m) */
  float angle;           /* sun: angular diameter (radians) */
  float size_x, size_y;  /* area: Blender size and size_y (m); disk: diameters */
  float spot_size;       /* spot: full cone angle (radians); the intensity
                            inside the cone: plm_conventions */
  float spot_blend;      /* spot: 0..1 */
} plm_light;

/* Fills a light with its struct_size and Blender's defaults for its type (white, 1000 W or
 * 1 W/m^2 for the sun, identity matrix, radius 0.1, angle 0.00918, size 1,
 * spot 45 degrees, blend 0.15). */
PLM_API void plm_light_default(plm_light* light, plm_light_type type);
PLM_API plm_status plm_scene_add_light(plm_scene* scene, const char* name, const plm_light* light,
                                       uint32_t* out_light_id);

/* Uniform world radiance over the whole sphere (Cycles background colour x
 * strength). Default black. */
PLM_API plm_status plm_scene_set_world(plm_scene* scene, const float radiance[3]);

/* An environment map as the world (Cycles' Environment Texture in the
 * world's Background): an equirectangular image, radiance = pixel x strength
 * (width x height linear RGB floats, the top row, +Z, first; at most 2^28
 * pixels). As in Blender a map-frame direction d reads the image at
 * u = 0.5 - atan2(d.y, d.x) / (2 pi), v = 0.5 + asin(d.z) / pi (the image's
 * centre looks along +X), bilinearly with periodic wrapping as Cycles' Linear
 * interpolation does. `rotation` (row-major 3x3, orthonormal; NULL =
 * identity) takes map-frame directions into the world: for a Blender Mapping
 * node of type Point, Vector or Normal whose rotation matrix is M it is M
 * transposed, of type Texture M itself. It replaces the uniform radiance of
 * plm_scene_set_world (and that call replaces the map). Importance-sampled
 * for direct light and photon emission; portals keep working.
 * plm_scene_set_world_map_file reads the image (EXR, HDR, PFM, PNG, JPEG,
 * BMP, TGA: the file types textures take; integer images are sRGB-decoded,
 * float images linear; grey images give R = G = B) when called. Errors: sizes, non-finite or
 * negative pixels (named by row and column), a rotation that is not
 * orthonormal, a strength outside [0, 1e30], an unreadable file (named). */
PLM_API plm_status plm_scene_set_world_map(plm_scene* scene, const float* rgb, uint32_t width, uint32_t height,
                                           const float rotation[9], float strength);
PLM_API plm_status plm_scene_set_world_map_file(plm_scene* scene, const char* path, const float rotation[9],
                                                float strength);

/* ---- CSG solids (exact analytic primitives and boolean trees) -------------
 *
 * A CSG solid is traced exactly: rays hit the primitives' true surfaces,
 * combined along each ray by the tree ([Thesis §4.1]). Primitives are Blender's
 * default add-primitive shapes in local space, placed by a 3x4 matrix
 * (row-major, local -> world; any invertible affine map):
 *   SPHERE radius 1; BOX [-1, 1]^3; CYLINDER radius 1, z in [-1, 1];
 *   CONE base radius 1 at z = -1, apex at z = +1; TORUS about z with
 *   major_radius / minor_radius (Blender: 1 and 0.25); PARABOLOID
 *   z = x^2 + y^2 for z in [0, 1], closed by a cap at z = 1; HALF_SPACE z <= 0.
 * Tree nodes: a LEAF names a primitive (first = its index); UNION,
 * INTERSECTION and DIFFERENCE (first child minus all others) have `count`
 * children listed from children[first]. Coincident faces follow fixed rules
 * (a face shared inside a union vanishes; see docs/design/geometry-kinds.md, "CSG solids") and overlapping
 * coplanar faces are reported as warnings. */
typedef enum plm_csg_shape {
  PLM_CSG_SPHERE = 0,
  PLM_CSG_BOX = 1,
  PLM_CSG_CYLINDER = 2,
  PLM_CSG_CONE = 3,
  PLM_CSG_TORUS = 4,
  PLM_CSG_PARABOLOID = 5,
  PLM_CSG_HALF_SPACE = 6
} plm_csg_shape;

typedef struct plm_csg_primitive {
  uint32_t struct_size; /* sizeof(plm_csg_primitive), the same in every element: see "Struct sizes" */
  uint32_t shape;     /* plm_csg_shape */
  uint32_t material;  /* material id (materials must be added first) */
  double matrix[12];  /* row-major 3x4, local -> world */
  double major_radius, minor_radius; /* TORUS only */
} plm_csg_primitive;

typedef enum plm_csg_op {
  PLM_CSG_UNION = 0,
  PLM_CSG_INTERSECTION = 1,
  PLM_CSG_DIFFERENCE = 2,
  PLM_CSG_LEAF = 3
} plm_csg_op;

typedef struct plm_csg_node {
  uint32_t struct_size; /* sizeof(plm_csg_node), the same in every element: see "Struct sizes" */
  uint32_t op;    /* plm_csg_op */
  uint32_t first; /* LEAF: primitive index; else index of its first child in children[] */
  uint32_t count; /* number of children (LEAF: ignored) */
} plm_csg_node;

/* Adds a CSG solid; its id is returned in out_csg. Errors name the solid and
 * the offending primitive or node (bad shapes, NaN or singular matrices,
 * torus radii, out-of-range indices, cycles, unbounded trees, trees needing
 * more than the per-ray crossing buffer). A solid alone blocks and reflects
 * light; to bake its light give it a carrier mesh. */
PLM_API plm_status plm_scene_add_csg(plm_scene* scene, const char* name, const plm_csg_primitive* primitives,
                                     uint32_t primitive_count, const plm_csg_node* nodes, uint32_t node_count,
                                     const uint32_t* children, uint32_t child_count, uint32_t root,
                                     uint32_t* out_csg);

/* Makes mesh (with a lightmap) the carrier of CSG solid csg: the mesh is the
 * artist's tessellation of the solid (e.g. Blender's evaluated Boolean
 * result). It is not traced -- the exact solid stands in for it -- and its
 * lightmap receives the solid's light: photons and direct light are gathered
 * on the solid's own texels (on the primitives' faces, split where a CSG
 * boundary cuts a texel), and each of the carrier's texels shows the solid's
 * texel at the nearest point of the exact surface. */
PLM_API plm_status plm_scene_set_csg_carrier(plm_scene* scene, uint32_t csg, uint32_t mesh);

/* ---- Bake ---------------------------------------------------------------- */

/* Two passes, as in [Thesis §3.5.2]: direct light is computed per texel with
 * shadow rays from stratified points inside the texel (direct_samples > 0),
 * and photons record only what arrives after their first bounce (indirect
 * light). With direct_samples = 0, photons carry direct light too.
 *
 * Quality: with target_error and time_budget both 0 the bake traces exactly
 * photon_count photons. Otherwise it traces photons in batches until the
 * estimated relative error (see plm_bake_stats.error_estimate) is at most
 * target_error, or time_budget seconds have passed, or photon_count photons
 * are traced (0 = no cap), whichever comes first. */
/* What a texel's value is. */
typedef enum plm_texel_value {
  PLM_TEXEL_CYCLES = 0, /* the average over the texel's central 0.5 x 0.5 texel square: what a
                           Cycles 3.4 bake converges to (it jitters its sample point by a quarter
                           texel around the centre, whatever its pixel filter) */
  PLM_TEXEL_AREA = 1    /* the average over the texel's whole covered area (smoother shadow edges) */
} plm_texel_value;

/* How sample points are drawn (docs/benchmarks/engine.md compares them). */
typedef enum plm_sampler {
  PLM_SAMPLER_DEFAULT = 0, /* Sobol where it lowers the error (direct pass), pseudo-random photons */
  PLM_SAMPLER_RANDOM = 1,  /* pseudo-random numbers everywhere */
  PLM_SAMPLER_SOBOL = 2    /* Owen-scrambled Sobol points everywhere, photon paths too */
} plm_sampler;

typedef struct plm_bake_settings {
  uint32_t struct_size;     /* sizeof(plm_bake_settings): see "Struct sizes" */
  uint64_t photon_count;    /* photons (the cap when a target or budget is set; 0 = none) */
  uint32_t max_bounces;     /* diffuse bounces after the first hit; 0 = direct only */
  uint32_t seed;            /* results are a function of seed only, not of threads */
  uint32_t thread_count;    /* 0 = all cores */
  uint32_t dilation;        /* texels filled around UV islands */
  double target_error;      /* relative RMS error to reach, e.g. 0.02; 0 = none */
  double time_budget;       /* seconds for the whole bake; 0 = none */
  uint32_t direct_samples;  /* shadow-ray points per texel and round; 0 = photons only */
  uint32_t filter_radius;   /* largest radius (texels) over which a texel's photon estimate pools
                               same-surface neighbours until it holds enough hits; 0 = none */
  uint32_t texel_value;     /* plm_texel_value (texels less than half covered, or whose centre is
                               not covered, are always averaged over their covered area) */
  uint32_t sampler;         /* plm_sampler */
  uint32_t directional;     /* 1: directional lightmaps (SH L1, see "Directional lightmaps"); 0: none */
} plm_bake_settings;

/* struct_size, photon_count 1,000,000, max_bounces 1024, seed 0, threads 0, dilation 8,
 * no target error, no time budget, direct_samples 64, filter_radius 2,
 * PLM_TEXEL_CYCLES, PLM_SAMPLER_DEFAULT, no directional lightmaps. */
PLM_API void plm_bake_settings_default(plm_bake_settings* settings);

/* Called from the thread that called plm_bake, at least every few tenths of a
 * second. fraction is the estimated fraction done in [0, 1]; stage names what
 * is running. Return 0 to cancel: plm_bake then returns PLM_ERROR_CANCELLED
 * promptly and produces no result. */
typedef int (*plm_progress_fn)(void* user_data, double fraction, const char* stage);

PLM_API plm_status plm_bake(plm_scene* scene, const plm_bake_settings* settings,
                            plm_progress_fn progress, void* user_data, plm_result** out_result);
PLM_API void plm_result_release(plm_result* result); /* NULL is fine */

/* ---- Live previews ----------------------------------------------------------
 *
 * plm_bake_with_preview bakes as plm_bake does and, while it runs, lets the
 * host look at the lightmaps: at the bake's check points (after each round
 * of the direct pass and after the pass, then between groups of photons,
 * several a second) it calls preview when at least preview_interval seconds
 * have passed since the last call ended (the call after the direct pass's
 * first round comes at once: direct light only, no photons yet). preview
 * runs on the thread that called plm_bake_with_preview while the bake waits;
 * it copies what it wants with plm_preview_copy_lightmap and returns quickly
 * (the handle is valid only during the call). Return 0 to cancel, as with
 * progress. Previews read the bake's sums and change nothing: the result is
 * bit for bit that of plm_bake with the same settings (with a time_budget,
 * previews take their share of the time like any work). preview NULL or
 * preview_interval 0: no previews (plm_bake). The final gather, when it runs,
 * is in the previews after it. */
typedef struct plm_preview plm_preview; /* the bake's state at one check point */
typedef int (*plm_preview_fn)(void* user_data, const plm_preview* preview);

PLM_API plm_status plm_bake_with_preview(plm_scene* scene, const plm_bake_settings* settings,
                                         plm_progress_fn progress, plm_preview_fn preview,
                                         double preview_interval, void* user_data, plm_result** out_result);

/* Photons traced so far (0 during and after the direct pass). */
PLM_API plm_status plm_preview_photons(const plm_preview* preview, uint64_t* out_photons);

/* The size of mesh mesh_id's lightmap (as plm_result_lightmap_size). */
PLM_API plm_status plm_preview_lightmap_size(const plm_preview* preview, uint32_t mesh_id, uint32_t* out_width,
                                             uint32_t* out_height);

/* Copies mesh mesh_id's lightmap at this state into rgb (width * height * 3
 * floats, irradiance / pi, rows bottom first): each covered texel's current
 * estimate, dilated like the final image; seams are not stitched and a
 * backup OL is not blended in (the final image does both). A mesh whose
 * texels come from an OL group or a CSG solid has no preview (known only at
 * the end): *out_written is then 0 and rgb is left as it was, else 1
 * (out_written may be NULL). */
PLM_API plm_status plm_preview_copy_lightmap(const plm_preview* preview, uint32_t mesh_id, float* rgb,
                                             int* out_written);

/* Sharded bakes (docs/farm.md): shard `shard` (0-based) of `shard_count` traces
 * its share of the photon batches and writes their sums to part_path
 * (atomically; the folder must exist), with the scene's hash, the settings and
 * scene_path (any label up to 255 bytes, e.g. the scene file; NULL for none).
 * plm_bake_merge adds every shard's sums and bakes the rest: the result is bit
 * for bit plm_bake's with the same settings, whatever the shard count. Needs a
 * photon count (no target error or time budget) and a scene without OL groups
 * or L-system objects; else PLM_ERROR_INVALID_ARGUMENT says why. */
PLM_API plm_status plm_bake_shard(plm_scene* scene, const plm_bake_settings* settings, uint32_t shard,
                                  uint32_t shard_count, const char* scene_path, const char* part_path,
                                  plm_progress_fn progress, void* user_data);
/* The texel ranges of a sharded bake (docs/farm.md): range `range` (0-based)
 * of `range_count` contiguous ranges of the covered texels, balanced by count.
 * PLM_TEXELS_DIRECT runs the direct pass of its texels and reads no parts; its
 * settings are plm_bake_shard's, and a target_error is allowed (the range's
 * rounds then bring its own texels' direct error under it). PLM_TEXELS_GATHER
 * runs the final gather of its texels over the photon parts and the direct
 * parts among part_paths (gather parts there are passed over; without direct
 * parts it runs the whole direct pass itself), with the settings the parts
 * hold (of `settings`, which may be NULL, only thread_count is used). Either
 * writes its part to part_path (atomically); plm_bake_merge takes these parts
 * beside the photon parts and is then still bit for bit plm_bake's (without a
 * target). Parts that do not belong together are refused, naming the part. */
typedef enum plm_texel_stage { PLM_TEXELS_DIRECT = 0, PLM_TEXELS_GATHER = 1 } plm_texel_stage;
PLM_API plm_status plm_bake_texels(plm_scene* scene, const plm_bake_settings* settings, uint32_t stage,
                                   uint32_t range, uint32_t range_count, const char* const* part_paths,
                                   uint32_t part_count, const char* scene_path, const char* part_path,
                                   plm_progress_fn progress, void* user_data);
/* What a part file holds: its bake's settings (thread_count 0; out_settings
 * must carry its struct_size, e.g. from plm_bake_settings_default), its shard
 * and shard count (a direct or gather part: its texel range and range count),
 * the scene_path it was given (copied, truncated to capacity - 1; scene_path
 * may be NULL). Any of the out pointers may be NULL. */
PLM_API plm_status plm_part_info(const char* part_path, plm_bake_settings* out_settings, uint32_t* out_shard,
                                 uint32_t* out_shard_count, char* scene_path, size_t scene_path_capacity);
/* Merges the parts of one sharded bake of `scene` (all of its shards, each once,
 * in any order; optionally every direct range and every gather range, each
 * once); a part that does not belong (another scene, seed, setting, engine
 * version, shard or range count, target error; damaged or truncated) is named
 * in the error.
 * thread_count is the merge's own (0 = all cores). */
PLM_API plm_status plm_bake_merge(plm_scene* scene, const char* const* part_paths, uint32_t part_count,
                                  uint32_t thread_count, plm_progress_fn progress, void* user_data,
                                  plm_result** out_result);

typedef struct plm_bake_stats {
  uint32_t struct_size;      /* sizeof(plm_bake_stats), set by the caller: see "Struct sizes" */
  uint64_t photons_emitted;
  uint64_t photon_hits;      /* hits stored into lightmaps and orientation lightmaps */
  uint64_t rays_traced;      /* photon rays */
  uint64_t paths_truncated;  /* paths stopped by max_bounces */
  double emitted_power;      /* W, sum over RGB channels / 3 */
  double seconds_setup;
  double seconds_trace;      /* photon pass */
  double seconds_total;
  uint64_t direct_samples;   /* shadow-ray samples of the direct pass */
  double seconds_direct;
  double error_estimate;     /* estimated relative RMS error over all covered texels:
                                sqrt(mean of squared standard errors) / mean value */
  double error_direct;       /* the part of error_estimate due to the direct pass */
  double error_median;       /* median over covered texels of (standard error / value) */
  double error_p95;          /* its 95th percentile */
  double error_above;        /* the share of covered texels whose (standard error / value) is above
                                twice the target error (twice error_estimate without a target) */
  uint64_t memory_estimate;  /* bytes the bake was estimated to need before it began; a bake
                                estimated to need more than the memory free is refused
                                (PLM_ERROR_OUT_OF_MEMORY, naming the largest lightmap) */
  double error_worst;        /* the largest estimated relative RMS error of one object, relative to
                                its own mean (objects under 64 covered texels are judged together
                                with their neighbours): what target_error bounds */
  uint32_t error_worst_mesh; /* that object's mesh id (of a group of small objects, the one with
                                most texels; of a CSG solid, its carrier); UINT32_MAX: none */
} plm_bake_stats;

PLM_API plm_status plm_result_stats(const plm_result* result, plm_bake_stats* out_stats);

/* Warnings about the scene or the bake (degenerate triangles skipped, no
 * lights, overlapping UVs...). The string lives as long as the result. */
PLM_API uint32_t plm_result_warning_count(const plm_result* result);
PLM_API const char* plm_result_warning(const plm_result* result, uint32_t index);

PLM_API plm_status plm_result_lightmap_size(const plm_result* result, uint32_t mesh_id,
                                            uint32_t* out_width, uint32_t* out_height);

/* Copies one lightmap into caller-owned buffers (any may be NULL):
 *   rgb       width * height * 3 floats, irradiance / pi
 *   error     width * height floats: standard error of the texel's mean RGB
 *   hits      width * height floats: photon hits recorded in the texel
 *   coverage  width * height floats: fraction of the texel covered by the
 *             mesh's UV islands (0 for dilated texels)
 * Rows bottom first (see top of file). */
PLM_API plm_status plm_result_copy_lightmap(const plm_result* result, uint32_t mesh_id,
                                            float* rgb, float* error, float* hits,
                                            float* coverage);

/* Writes one lightmap as an OpenEXR file with channels R, G, B, error, hits.
 * The file appears atomically (written to a temporary name, then renamed). */
PLM_API plm_status plm_result_write_exr(const plm_result* result, uint32_t mesh_id,
                                        const char* path);

/* A lightmap held by the caller (an atlas page assembled from several
 * lightmaps, say) written as plm_result_write_exr writes one: channels R, G,
 * B, error, hits, rows bottom first, atomically. rgb holds width * height * 3
 * floats; error and hits width * height floats each, or NULL (written as 0). */
PLM_API plm_status plm_write_lightmap_exr(const char* path, uint32_t width, uint32_t height,
                                          const float* rgb, const float* error, const float* hits);

/* A map of one value per texel (the add-on's heat map of relative errors)
 * written as R = G = B in 16-bit floats (3 significant digits, half the
 * size of floats), ZIP-compressed, rows bottom first, atomically. values
 * holds width * height floats. */
PLM_API plm_status plm_write_heat_map_exr(const char* path, uint32_t width, uint32_t height, const float* values);

/* Reads an EXR written by plm_result_write_exr or plm_write_lightmap_exr into
 * caller-owned buffers. With rgb, error and hits all NULL only the size is
 * returned; otherwise *width and *height must hold the file's size (the call
 * fails naming both sizes if not). Channels the file lacks read as 0. */
PLM_API plm_status plm_read_lightmap_exr(const char* path, uint32_t* width, uint32_t* height, float* rgb,
                                         float* error, float* hits);

/* ---- Light groups ------------------------------------------------------------
 *
 * Light groups split a bake by what lights it (Blender's View Layer > Light
 * Groups): one bake gives each lightmap one layer per group, from the same
 * photons and direct samples, and a host mixes the layers at any strength and
 * tint without baking again (light is additive). Lights, meshes' emission and
 * the world belong to the default group (id 0) unless put into a declared
 * one. The layers are the default group (where an emitter is in it) and then
 * every declared group in order; they add up to the lightmap (up to float
 * rounding). Each layer carries its own error estimate. Sharded bakes carry
 * the layers in their part files, and the merge gives them bit for bit as
 * plm_bake does. Only ordinary lightmaps are split: a bake fails for a scene
 * with light groups and OL groups, CSG solids or L-system objects. */

/* Declares a light group; *out_group gets its id (1, 2, ... in order). The
 * name (at most 64 of letters, digits, '_' and '-'; not "default") names the
 * layer and its files. */
PLM_API plm_status plm_scene_add_light_group(plm_scene* scene, const char* name, uint32_t* out_group);
/* Puts light `light`, the emission of mesh `mesh`, or the world into group
 * `group` (0: the default group). */
PLM_API plm_status plm_scene_set_light_group(plm_scene* scene, uint32_t light, uint32_t group);
PLM_API plm_status plm_scene_set_mesh_light_group(plm_scene* scene, uint32_t mesh, uint32_t group);
PLM_API plm_status plm_scene_set_world_light_group(plm_scene* scene, uint32_t group);

/* The result's layers: their count (0 without light groups), and layer
 * `layer`'s name ("default" for the default group; NULL for a bad index)
 * and estimated relative error over the covered texels. */
PLM_API uint32_t plm_result_layer_count(const plm_result* result);
PLM_API const char* plm_result_layer_name(const plm_result* result, uint32_t layer);
PLM_API plm_status plm_result_layer_error(const plm_result* result, uint32_t layer, double* out_relative_error);
/* Layer `layer` of mesh `mesh_id`'s lightmap into caller-owned buffers (rgb:
 * width * height * 3 floats, error: width * height, either may be NULL),
 * rows bottom first, as plm_result_copy_lightmap. */
PLM_API plm_status plm_result_copy_lightmap_layer(const plm_result* result, uint32_t mesh_id, uint32_t layer,
                                                  float* rgb, float* error);
/* The layer as an OpenEXR file as plm_result_write_exr writes the lightmap
 * (channels R, G, B, error, hits; hits are the whole lightmap's). */
PLM_API plm_status plm_result_write_layer_exr(const plm_result* result, uint32_t mesh_id, uint32_t layer,
                                              const char* path);

/* ---- Directional lightmaps ----------------------------------------------------
 *
 * With plm_bake_settings.directional, each lightmap also keeps the direction
 * of its light, so that normal maps and bump respond to baked light: per
 * texel and channel the first-order spherical harmonics (SH L1) of the
 * light, in Godot 4's layout and normalisation. Band 0 is L0, bands 1, 2, 3
 * are L1 m = -1, 0, 1 (along the world's y, z and x axes: Blender's, z up).
 * A surface of unit normal n (world space) at the texel receives
 *
 *     value(n) = 0.282095 L0 + 0.32573 (L1_-1 n.y + L1_0 n.z + L1_1 n.x)
 *
 * (irradiance / pi, the lightmap's units). At the texel's own normal this
 * is the lightmap's value; it changes with n as the texel's light does to
 * first order, and for light from all of the hemisphere alike it is that
 * light's exact SH L1 (docs/design/directional.md). Only ordinary lightmaps
 * get directions: a bake with directional and light groups, OL groups, CSG
 * solids or L-system objects fails. Sharded bakes carry them in their part
 * files, and the merge gives them bit for bit as plm_bake does. */

/* Whether the result has directional lightmaps (1) or not (0). */
PLM_API uint32_t plm_result_directional(const plm_result* result);
/* SH band `band` (0: L0, 1: L1_-1, 2: L1_0, 3: L1_1) of mesh `mesh_id`'s
 * lightmap into a caller-owned buffer of width * height * 3 floats, rows
 * bottom first, as plm_result_copy_lightmap. */
PLM_API plm_status plm_result_copy_lightmap_sh(const plm_result* result, uint32_t mesh_id, uint32_t band, float* rgb);
/* The band as an OpenEXR file (channels R, G, B; hits as the lightmap's). */
PLM_API plm_status plm_result_write_sh_exr(const plm_result* result, uint32_t mesh_id, uint32_t band,
                                           const char* path);

/* ---- Orientation lightmaps (OL) -------------------------------------------
 *
 * An OL group stores the light of its meshes by surface normal instead of by
 * UV texel ([Thesis §6.2]): one map over the sphere of directions, in N x N bins
 * of an equal-area octahedral map (bin = row * N + column; column along u,
 * row along v, row 0 at v near 0; a unit normal n maps to (u, v) as in
 * Clarberg 2008 / pbrt-v4's EqualSphereToSquare with the +z hemisphere in the
 * inner diamond). Every point of the group whose normal falls in a bin shows
 * that bin's value: flux recorded there / (pi * area of the group's surface
 * whose normal falls in the bin) = irradiance / pi, like a texel. Such meshes
 * need no UVs; light still bounces off their real geometry.
 *
 * Recording: photons record hits on the front side of an OL mesh's triangles
 * (the side their winding faces, as lightmaps do), by the triangle's
 * geometric normal. OL meshes get no per-texel direct pass: their direct
 * light comes from the photons, at every depth, whatever direct_samples is
 * (direct_samples still drives the lightmapped meshes). The error of a bin is
 * the spread of 16 independent photon groups (photon batches of 4096 taken
 * round robin). target_error is measured over lightmap texels only; OLs do
 * not steer when a bake stops. */

/* Adds an empty OL group and returns its index in out_group (0, 1, ...).
 * resolution: bins per side, 1..1024, or 0 = automatic (16 x 16). name may be
 * NULL. A group that ends up with no meshes gives a warning at bake time and
 * a black map. */
PLM_API plm_status plm_scene_add_ol_group(plm_scene* scene, const char* name, uint32_t resolution,
                                          uint32_t* out_group);

/* Puts a mesh into an OL group (a later call moves it to another group).
 * Errors name the mesh and the group. A mesh in a group that also has a
 * lightmap gets its lightmap resolved from the OL: each covered texel shows
 * the OL at the texel's normal (value, error and hits of that bin), so an
 * OL-lit object comes back as an ordinary lightmap image; its texels take no
 * part in the direct pass, the photon texel sums or target_error. */
PLM_API plm_status plm_scene_set_mesh_ol_group(plm_scene* scene, uint32_t mesh, uint32_t group);

/* Makes OL group `group` a backup (backup != 0) or a resolving group (0, the
 * default). The lightmapped meshes of a backup group keep their own texels
 * (direct pass, photon sums, target_error), the OL gathers only their
 * indirect hits (those the texels record), and each texel's indirect estimate
 * is combined with the OL at its normal by inverse variance: the OL's variance
 * plus its squared bias against the texels (estimated per lightmap as the
 * mean of (texel - OL)^2 - their variances). Noisy texels lean on the OL,
 * well-sampled ones keep their own detail. Meshes without a lightmap in a
 * backup group record into the OL as usual. */
PLM_API plm_status plm_scene_set_ol_group_backup(plm_scene* scene, uint32_t group, int backup);

/* Per-bin areas of the group's subdivision meshes (plm_scene_add_subdiv_mesh)
 * from samples of their limit surface instead of their refined triangles
 * (default off). Photons hit the refined triangles, so the OL then describes
 * the smooth limit surface: its values are lower by the ratio of triangle area
 * to limit area (12 % for a cube cage at level 1, 3 % at level 2, under 0.3 %
 * from level 3 or for fine cages). Other meshes of the group are unaffected. */
PLM_API plm_status plm_scene_set_ol_group_limit_area(plm_scene* scene, uint32_t group, int limit_area);

/* Reads one OL of a result. The pointers stay valid as long as the result;
 * any output may be NULL.
 *   rgb         resolution^2 * 3 floats, irradiance / pi (0 in bins whose
 *               area is 0: no surface of the group has that normal)
 *   error       resolution^2 floats: standard error of the bin's mean RGB
 *   resolution  bins per side */
PLM_API plm_status plm_result_ol(const plm_result* result, uint32_t group, const float** rgb,
                                 const float** error, uint32_t* resolution);

/* Per-bin covered area (m^2) and photon hits, resolution^2 floats each, valid
 * as long as the result; either may be NULL. The area is what the bin's flux
 * is divided by: each triangle's exact area shared among the (up to) four bins
 * a lookup at its normal interpolates, by the lookup's bilinear weights, as
 * its hits' flux is (limit-area subdivision meshes: their limit surface's area
 * in the bin of its normal). A hit is counted in the bin of its normal. */
PLM_API plm_status plm_result_ol_bins(const plm_result* result, uint32_t group, const float** area,
                                      const float** hits);

typedef struct plm_ol_stats {
  uint32_t struct_size;  /* sizeof(plm_ol_stats), set by the caller: see "Struct sizes" */
  uint32_t resolution;   /* bins per side */
  uint32_t mesh_count;   /* meshes in the group */
  uint64_t hits;         /* photon hits recorded */
  double area;           /* total front-side area of the group's triangles (m^2); for a
                            subdivision mesh, of its limit surface (sampled) */
  double flux;           /* W (RGB mean) recorded: sum over bins of value * pi * area */
  double orphan_flux;    /* W (RGB mean) of hits in bins without area, moved to neighbouring
                            bins; 0 unless normals and areas disagree */
} plm_ol_stats;

PLM_API plm_status plm_result_ol_stats(const plm_result* result, uint32_t group, plm_ol_stats* out_stats);

/* Writes one OL as an OpenEXR file of resolution x resolution pixels with
 * channels R, G, B, area, error, hits (top row = the last row of bins, as for
 * lightmaps). The file appears atomically. */
PLM_API plm_status plm_result_write_ol_exr(const plm_result* result, uint32_t group, const char* path);

/* ---- L-system objects (plants traced as cyclic scene graphs) ------------
 *
 * An L-system object is a plant described by rules in the L-system language
 * of docs (axiom, productions, depth, step, angle, width; see
 * native/src/lsystem/language/lsystem.h). It is traced without flattening ([Thesis
 * §4.3-4.4]): a graph of node classes expanded on demand per thread, with an
 * LRU cache of expanded instances. Turtle primitives are the CSG shapes
 * CYLINDER (F), SPHERE (@O), CONE (@C) and BOX (@L, @B).
 *
 * Light: an L-system object has no texels. Its light is stored in
 * orientation lightmaps by surface normal ([Thesis ch. 7]): one root OL for the
 * whole object, plus one "stub" OL per node instance ol_level derivation
 * levels below the root (instances are named by the key of their traversal
 * path), so that different branches can differ. Photons record their hits at
 * every depth (no per-texel direct pass). Bin areas are estimated at bake
 * time by sampling the faces of the flattened primitives (at most 2^21; at
 * least 16 samples per face, 65536 shared by area) and binning the normals.
 * Hits on the inside of a primitive (where primitives overlap) are not
 * recorded; the overlapped surface still counts in the areas. */
typedef struct plm_lsystem_settings {
  uint32_t struct_size;    /* sizeof(plm_lsystem_settings): see "Struct sizes" */
  uint32_t depth;          /* derivation steps; 0 = the rules' `depth:` */
  uint32_t seed;           /* stochastic productions */
  double matrix[12];       /* row-major 3x4 placement, local -> world: a rotation (or mirror) times a
                              uniform scale, plus a translation; shear and non-uniform scale are errors */
  double step, angle, width; /* < 0: the rules' `step:`, `angle:` (degrees), `width:` (a diameter) */
  const uint32_t* materials; /* turtle material index i (set with ') -> scene material materials[i];
                                indices past the end use the last entry. NULL / 0 entries: material 0 */
  uint32_t material_count;
  uint32_t ol_level;       /* stub OLs one per node instance this many levels below the root
                              (level 1 is the axiom's modules, level k their (k-1)-th descendants;
                              primitives drawn above that level form stubs of their own node);
                              0 = only the root OL. More than 2^20 stub bins in all (4096 stubs of
                              16^2 bins): only the root OL, with a warning */
  uint32_t ol_resolution;  /* bins per side of every OL of the object, 1..1024; 0 = 16 */
  uint64_t cache_bytes;    /* expanded-instance cache per tracing thread; 0 = 64 MiB */
} plm_lsystem_settings;

/* struct_size, depth 0, seed 0, identity matrix, step/angle/width -1, no materials,
 * ol_level 0, ol_resolution 0, cache_bytes 0. */
PLM_API void plm_lsystem_settings_default(plm_lsystem_settings* settings);

/* Parses the rules and builds the object's graph now; its id (0, 1, ...) is
 * returned in out_id. Errors name the object: parse errors with "line L,
 * column C", systems the graph cannot trace (context-sensitive productions,
 * rand()), depth over 63 levels, NaN or non-similarity matrices, material ids
 * that do not exist (materials must be added first). The object blocks and
 * reflects light, shadows other objects in the direct pass, and gets OLs. */
PLM_API plm_status plm_scene_add_lsystem(plm_scene* scene, const char* name, const char* rules,
                                         const plm_lsystem_settings* settings, uint32_t* out_id);

/* Flattens a system for viewport previews: at most max_primitives primitives
 * in world space (the placement included), in string order. settings may be
 * NULL (defaults). Outputs (each may be NULL, e.g. all NULL to count):
 *   shapes     one plm_csg_shape per primitive (CYLINDER 2, SPHERE 0, CONE 3, BOX 1)
 *   matrices   12 doubles per primitive: the canonical CSG shape -> world, row-major 3x4
 *   materials  one per primitive: the turtle index mapped through
 *              settings->materials when given, else the turtle index itself
 * out_count: primitives written; out_truncated: 1 if max_primitives was hit. */
PLM_API plm_status plm_lsystem_flatten(const char* rules, const plm_lsystem_settings* settings,
                                       uint64_t max_primitives, uint32_t* shapes, double* matrices,
                                       uint32_t* materials, uint64_t* out_count, int* out_truncated);

/* The light at count surface points of L-system object `lsystem`: points and
 * normals 3 floats per item (world space), out_rgb 3 floats per item,
 * irradiance / pi. Each point finds the primitive it lies on by a short ray
 * (from point + eps * normal along -normal, eps = 1e-3 of the object's size)
 * and takes the stub OL of that primitive's instance at ol_level, looked up
 * at the normal, if that stub's bin for the normal holds at least 16 hits;
 * otherwise (no stub, too few hits, no primitive found) the root OL: [Thesis]'s
 * "lowest level with enough hits". Safe to call from several threads. */
PLM_API plm_status plm_result_lsystem_lookup(const plm_result* result, uint32_t lsystem, uint64_t count,
                                             const float* points, const float* normals, float* out_rgb);

typedef struct plm_lsystem_stats {
  uint32_t struct_size;    /* sizeof(plm_lsystem_stats), set by the caller: see "Struct sizes" */
  uint64_t stubs;          /* stub OLs that received hits */
  uint64_t stub_instances; /* instances at ol_level in the flattened object (areas known) */
  uint64_t hits;           /* photon hits recorded on the object */
  uint64_t classes;        /* node classes of the graph */
  uint64_t primitives;     /* flattened primitives used for the areas */
  uint32_t truncated;      /* 1 if flattening for the areas hit its cap (2^21 primitives): the areas
                              of the first 2^21 are scaled up to the whole object, with a warning */
  uint32_t resolution;     /* bins per side of its OLs */
  uint64_t cache_hits, cache_misses; /* expansion cache over all threads, since the object was added
                                        (bakes and lookups) */
  uint64_t cache_bytes;    /* peak cached bytes summed over the thread caches */
  uint64_t class_bytes;    /* the immutable graph */
  double area;             /* total surface area of the primitives (m^2, estimated) */
  double flux;             /* W (RGB mean) arriving on the object: sum over root bins of value * pi * area */
} plm_lsystem_stats;

PLM_API plm_status plm_result_lsystem_stats(const plm_result* result, uint32_t lsystem, plm_lsystem_stats* out_stats);

#ifdef __cplusplus
}
#endif

#endif /* PHOTONLM_PHOTONLM_H */
