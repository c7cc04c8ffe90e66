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

/**
 * An RGBM lightmap as a linear half-float texture of rgb x m (the decoded value over `range`;
 * the material's lightMapIntensity, pi x range, makes it irradiance). Sampled as the file says
 * (linear, no mipmaps, clamped), on UV set `texCoord`.
 */
export async function lightmapTexture(parser, info) {
  const textureDef = parser.json.textures[info.texture];
  const png = await decodePng(await imageBytes(parser, textureDef.source));
  const { width, height, data } = png;
  const half = new Uint16Array(width * height * 4);
  for (let i = 0; i < width * height; i++) {
    const m = data[4 * i + 3] / 255;
    for (let c = 0; c < 3; c++) half[4 * i + c] = THREE.DataUtils.toHalfFloat((data[4 * i + c] / 255) * m);
    half[4 * i + 3] = THREE.DataUtils.toHalfFloat(1);
  }
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
 * The material that shows `source` (GLTFLoader's) with `lightMap`: a Lambert material keeps its base
 * colour (factor, texture, vertex colours), alpha and emission; with no lights in the scene it
 * shades lightMap x lightMapIntensity x albedo / pi (three.js's lightmap is irradiance), which for
 * intensity = pi x range is albedo x the lightmap's value, Blender's preview.
 */
function lambertWith(source, lightMap, info) {
  const material = new THREE.MeshLambertMaterial({
    name: source.name, color: source.color, map: source.map, vertexColors: source.vertexColors,
    side: source.side, transparent: source.transparent, opacity: source.opacity, alphaTest: source.alphaTest,
    alphaMap: source.alphaMap, emissive: source.emissive, emissiveMap: source.emissiveMap,
    emissiveIntensity: source.emissiveIntensity, lightMap, lightMapIntensity: info.intensity,
  });
  material.userData = source.userData;
  return material;
}

/**
 * Gives every material of `gltf` with photonlm's extras its decoded lightmap. Returns the number of
 * materials given one; each lightmap texture is decoded once.
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
        materials.set(source.uuid, textures.get(info.texture).then((t) => lambertWith(source, t, info)));
      }
      return materials.get(source.uuid);
    }));
    mesh.material = Array.isArray(mesh.material) ? replaced : replaced[0];
  }
  return materials.size;
}
