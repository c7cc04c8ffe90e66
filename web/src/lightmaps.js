// photonlm's lightmaps in a glTF loaded by three.js's GLTFLoader: each material whose extras hold
// `photonlm_lightmap` (GLTFLoader puts them in material.userData) gets its lightmap decoded from RGBM
// and is shaded as Blender's lightmap preview shades it: albedo x lightmap value, no other light.
import * as THREE from 'three';
import { decodePng } from './png.js';

export const EXTRAS_KEY = 'photonlm_lightmap';

/** The bytes of glTF image `index`: from a buffer view (a .glb) or its URI. */
async function imageBytes(parser, index) {
  const image = parser.json.images[index];
  if (image.bufferView !== undefined) {
    return new Uint8Array(await parser.getDependency('bufferView', image.bufferView));
  }
  const url = THREE.LoaderUtils.resolveURL(image.uri, parser.options.path);
  const response = await fetch(url);
  if (!response.ok) throw new Error(`image ${image.uri}: HTTP ${response.status}`);
  return new Uint8Array(await response.arrayBuffer());
}

/** An RGBM texture's values over its range (rgb x m, 4 floats a texel, rows top first) and its size. */
async function decodeRgbm(parser, textureIndex) {
  const textureDef = parser.json.textures[textureIndex];
  const { width, height, data } = await decodePng(await imageBytes(parser, textureDef.source));
  const values = new Float32Array(width * height * 4);
  for (let i = 0; i < width * height; i++) {
    const m = data[4 * i + 3] / 255;
    for (let c = 0; c < 3; c++) values[4 * i + c] = (data[4 * i + c] / 255) * m;
    values[4 * i + 3] = 1;
  }
  return { width, height, values };
}

/** A signed RGBM texture's values (value = (2 rgb - 1) x a x range: the SH bands), 4 floats a texel. */
async function decodeSignedRgbm(parser, textureIndex, range) {
  const textureDef = parser.json.textures[textureIndex];
  const { width, height, data } = await decodePng(await imageBytes(parser, textureDef.source));
  const values = new Float32Array(width * height * 4);
  for (let i = 0; i < width * height; i++) {
    const m = (data[4 * i + 3] / 255) * range;
    for (let c = 0; c < 3; c++) values[4 * i + c] = (2 * (data[4 * i + c] / 255) - 1) * m;
    values[4 * i + 3] = 1;
  }
  return { width, height, values };
}

/** A half-float texture of `values` (4 floats a texel), sampled as the file says, on UV set `texCoord`. */
function halfTexture(width, height, values, info) {
  const half = new Uint16Array(values.length);
  for (let i = 0; i < values.length; i++) half[i] = THREE.DataUtils.toHalfFloat(values[i]);
  // Rows top first, as the PNG: glTF's v = 0 is the image's top row, three.js's t = 0 the first row.
  const texture = new THREE.DataTexture(half, width, height, THREE.RGBAFormat, THREE.HalfFloatType);
  texture.colorSpace = THREE.NoColorSpace;
  texture.magFilter = THREE.LinearFilter;
  texture.minFilter = THREE.LinearFilter;
  texture.generateMipmaps = false;
  texture.wrapS = texture.wrapT = THREE.ClampToEdgeWrapping;
  texture.flipY = false;
  texture.channel = info.texCoord;  // TEXCOORD_1 is three.js's uv1
  texture.name = info.image || `lightmap ${info.texture}`;
  texture.needsUpdate = true;
  return texture;
}

/**
 * An RGBM lightmap as a linear half-float texture of rgb x m (the decoded value over `range`;
 * the material's lightMapIntensity, pi x range, makes it irradiance). Sampled as the file says
 * (linear, no mipmaps, clamped), on UV set `texCoord`. With light groups (info.layers), the
 * texture also carries its layers' values (texture.userData.layers) for the mixer (mixLayers).
 */
export async function lightmapTexture(parser, info) {
  const { width, height, values } = await decodeRgbm(parser, info.texture);
  const texture = halfTexture(width, height, values, info);
  if (info.layers && info.layers.length) {
    texture.userData.range = info.range;
    texture.userData.layers = await Promise.all(info.layers.map(async (layer) => {
      const decoded = await decodeRgbm(parser, layer.texture);
      if (decoded.width !== width || decoded.height !== height) {
        throw new Error(`light group ${layer.group}: its lightmap is ${decoded.width} x ${decoded.height}, ` +
                        `the lightmap ${width} x ${height}`);
      }
      return { group: layer.group, scale: layer.range / info.range, values: decoded.values };
    }));
    texture.userData.whole = values;
  }
  return texture;
}

/**
 * The light groups of the lightmaps of `textures` (lightmapTexture's): each one's strength and tint
 * as the file had them (the first material that names it), in order of appearance.
 */
export function lightGroups(infos) {
  const groups = new Map();
  for (const info of infos) {
    for (const layer of info.layers || []) {
      if (!groups.has(layer.group)) {
        groups.set(layer.group, { strength: layer.strength ?? 1, tint: (layer.tint || [1, 1, 1]).slice(0, 3) });
      }
    }
  }
  return groups;
}

/**
 * Sets every lightmap with layers to sum over its layers of layer x strength x tint (`groups`:
 * name -> {strength, tint}), as Blender's Light Groups preview does; with every strength 1 and
 * every tint white, the lightmap as baked (the layers add up to it).
 */
export function mixLayers(textures, groups) {
  const identity = [...groups.values()].every((g) => g.strength === 1 && g.tint.every((t) => t === 1));
  for (const texture of textures) {
    const { layers, whole } = texture.userData;
    if (!layers) continue;
    const half = texture.image.data;
    if (identity) {
      for (let i = 0; i < whole.length; i++) half[i] = THREE.DataUtils.toHalfFloat(whole[i]);
    } else {
      const n = whole.length / 4;
      const sum = new Float32Array(3 * n);
      for (const layer of layers) {
        const g = groups.get(layer.group);
        for (let c = 0; c < 3; c++) {
          const k = layer.scale * g.strength * g.tint[c];
          if (k === 0) continue;
          for (let i = 0; i < n; i++) sum[3 * i + c] += k * layer.values[4 * i + c];
        }
      }
      for (let i = 0; i < n; i++) {
        for (let c = 0; c < 3; c++) half[4 * i + c] = THREE.DataUtils.toHalfFloat(sum[3 * i + c]);
      }
    }
    texture.needsUpdate = true;
  }
}

/**
 * The material that shows `source` (GLTFLoader's) with `lightMap`: a Lambert material keeps its base
 * colour (factor, texture, vertex colours), alpha, emission and normal map (which directional
 * lightmaps' bands are evaluated at); with no lights in the scene it
 * shades lightMap x lightMapIntensity x albedo / pi (three.js's lightmap is irradiance), which for
 * intensity = pi x range is albedo x the lightmap's value, Blender's preview.
 */
// Directional lightmaps (extras' `sh`, docs/gltf.md): the lightmap's irradiance term becomes
// pi x value(n) = pi (V / 2 + 0.32573 (L1_1 n.x + L1_-1 n.y + L1_0 n.z)), n the shaded normal (normal
// map included) in world space (glTF's axes, three.js's), clamped at 0.
const SH_TARGET = 'vec3 lightMapIrradiance = lightMapTexel.rgb * lightMapIntensity;';
const SH_UNIFORMS = 'uniform sampler2D photonlmShX;\nuniform sampler2D photonlmShY;\nuniform sampler2D photonlmShZ;\n';
const SH_IRRADIANCE = `vec3 photonlmN = normalize( ( vec4( geometryNormal, 0.0 ) * viewMatrix ).xyz );
		vec3 lightMapIrradiance = max( lightMapTexel.rgb * lightMapIntensity * 0.5 + ${(Math.PI * 0.32573500793527993).toFixed(9)} * (
			texture2D( photonlmShX, vLightMapUv ).rgb * photonlmN.x + texture2D( photonlmShY, vLightMapUv ).rgb * photonlmN.y +
			texture2D( photonlmShZ, vLightMapUv ).rgb * photonlmN.z ), vec3( 0.0 ) );`;

/** The SH bands of `info` (extras' `sh`) as textures along x, y and z, or null. */
async function shTextures(parser, info) {
  if (!info.sh) return null;
  const byM = new Map(info.sh.bands.map((b) => [b.m, b]));
  const axes = [1, -1, 0].map((m) => byM.get(m));  // x: L1_1, y: L1_-1, z: L1_0
  if (axes.some((b) => !b)) throw new Error(`lightmap ${info.image}: its SH lacks a band`);
  return Promise.all(axes.map(async (b) => {
    const { width, height, values } = await decodeSignedRgbm(parser, b.texture, b.range);
    return halfTexture(width, height, values, info);
  }));
}

function lambertWith(source, lightMap, info, sh) {
  const material = new THREE.MeshLambertMaterial({
    name: source.name, color: source.color, map: source.map, vertexColors: source.vertexColors,
    side: source.side, transparent: source.transparent, opacity: source.opacity, alphaTest: source.alphaTest,
    alphaMap: source.alphaMap, emissive: source.emissive, emissiveMap: source.emissiveMap,
    emissiveIntensity: source.emissiveIntensity, lightMap, lightMapIntensity: info.intensity,
    normalMap: source.normalMap, normalMapType: source.normalMapType, normalScale: source.normalScale,
    bumpMap: source.bumpMap, bumpScale: source.bumpScale,
  });
  material.userData = source.userData;
  if (sh) {
    if (!THREE.ShaderChunk.lights_fragment_maps.includes(SH_TARGET)) {
      throw new Error('this three.js shades lightmaps otherwise: directional lightmaps need its lights_fragment_maps');
    }
    material.onBeforeCompile = (shader) => {
      shader.uniforms.photonlmShX = { value: sh[0] };
      shader.uniforms.photonlmShY = { value: sh[1] };
      shader.uniforms.photonlmShZ = { value: sh[2] };
      shader.fragmentShader = SH_UNIFORMS + shader.fragmentShader.replace(
        '#include <lights_fragment_maps>',
        THREE.ShaderChunk.lights_fragment_maps.replace(
          SH_TARGET, SH_IRRADIANCE));
    };
    material.customProgramCacheKey = () => 'photonlm-sh';
  }
  return material;
}

/**
 * Gives every material of `gltf` with photonlm's extras its decoded lightmap. Returns the number of
 * materials given one, the lightmap textures (each decoded once) and the light groups
 * (lightGroups) of the file.
 */
export async function applyLightmaps(gltf) {
  const textures = new Map();
  const materials = new Map();
  const meshes = [];
  gltf.scene.traverse((object) => { if (object.isMesh) meshes.push(object); });
  for (const mesh of meshes) {
    const list = Array.isArray(mesh.material) ? mesh.material : [mesh.material];
    const replaced = await Promise.all(list.map(async (source) => {
      const info = source && source.userData[EXTRAS_KEY];
      if (!info) return source;
      if (info.encoding !== 'RGBM') throw new Error(`lightmap encoding ${info.encoding} is not RGBM`);
      if (!materials.has(source.uuid)) {
        if (!textures.has(info.texture)) textures.set(info.texture, lightmapTexture(gltf.parser, info));
        const sh = shTextures(gltf.parser, info);
        materials.set(source.uuid, Promise.all([textures.get(info.texture), sh])
          .then(([t, bands]) => lambertWith(source, t, info, bands)));
      }
      return materials.get(source.uuid);
    }));
    mesh.material = Array.isArray(mesh.material) ? replaced : replaced[0];
  }
  const infos = [];
  gltf.scene.traverse((object) => {
    if (!object.isMesh) return;
    for (const m of Array.isArray(object.material) ? object.material : [object.material]) {
      if (m && m.userData[EXTRAS_KEY]) infos.push(m.userData[EXTRAS_KEY]);
    }
  });
  return { count: materials.size, textures: await Promise.all(textures.values()), groups: lightGroups(infos) };
}
