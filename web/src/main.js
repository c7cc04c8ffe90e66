// photonlm's web viewer: a .glb exported with its lightmaps, shaded as Blender's lightmap preview
// under the Standard view transform.
//
// Query parameters:
//   file=URL            the .glb (required)
//   cam=x,y,z           camera position     } in glTF's axes (y up; Blender's (x, y, z) is (x, z, -y)),
//   target=x,y,z        point looked at     } instead of the file's first camera or a view of the
//   fov=DEGREES         vertical field of view (default 50)   whole scene
//   exposure=STOPS      exposure, as Blender's Film exposure (default 0)
//   mix=G:S,G:S         light groups' strengths (default: as the file was written; tints as written)
//   ui=0                no panel (screenshots)
import * as THREE from 'three';
import { GLTFLoader } from 'three/examples/jsm/loaders/GLTFLoader.js';
import { OrbitControls } from 'three/examples/jsm/controls/OrbitControls.js';
import { applyLightmaps, mixLayers } from './lightmaps.js';

const params = new URLSearchParams(window.location.search);

function vector(name) {
  const text = params.get(name);
  if (text === null) return null;
  const v = text.split(',').map(Number);
  if (v.length !== 3 || !v.every(Number.isFinite)) throw new Error(`${name}=${text}: expected three numbers x,y,z`);
  return new THREE.Vector3(...v);
}

function number(name, fallback) {
  const text = params.get(name);
  if (text === null) return fallback;
  const v = Number(text);
  if (!Number.isFinite(v)) throw new Error(`${name}=${text}: expected a number`);
  return v;
}

const status = document.getElementById('status');
const panel = document.getElementById('panel');
const slider = document.getElementById('exposure');
const exposureLabel = document.getElementById('exposure-value');

const renderer = new THREE.WebGLRenderer({ antialias: true });
renderer.setPixelRatio(window.devicePixelRatio);
renderer.setSize(window.innerWidth, window.innerHeight);
renderer.setClearColor(0x000000, 1);
renderer.outputColorSpace = THREE.SRGBColorSpace;
// Linear tone mapping is exposure x colour clipped to [0, 1], then the sRGB curve: Blender's
// Standard view transform with its Film exposure.
renderer.toneMapping = THREE.LinearToneMapping;
document.body.appendChild(renderer.domElement);

const scene = new THREE.Scene();
const camera = new THREE.PerspectiveCamera(50, window.innerWidth / window.innerHeight, 0.01, 1000);
const controls = new OrbitControls(camera, renderer.domElement);

function render() {
  renderer.render(scene, camera);
}

function setExposure(stops) {
  renderer.toneMappingExposure = 2 ** stops;
  slider.value = String(stops);
  exposureLabel.textContent = `${stops >= 0 ? '+' : ''}${stops.toFixed(1)}`;
  render();
}

/** The view: the URL's camera, else the file's first camera, else the whole scene from the front. */
function placeCamera(gltf) {
  const box = new THREE.Box3().setFromObject(gltf.scene);
  const center = box.getCenter(new THREE.Vector3());
  const size = box.getSize(new THREE.Vector3()).length() || 1;
  const position = vector('cam');
  if (position) {
    camera.position.copy(position);
    camera.fov = number('fov', 50);
    controls.target.copy(vector('target') || center);
  } else if (gltf.cameras.length > 0) {
    const source = gltf.cameras[0];
    source.updateWorldMatrix(true, false);
    camera.position.setFromMatrixPosition(source.matrixWorld);
    if (source.isPerspectiveCamera) camera.fov = source.fov;
    const forward = new THREE.Vector3(0, 0, -1).transformDirection(source.matrixWorld);
    const distance = Math.max(center.clone().sub(camera.position).dot(forward), 0.1 * size);
    controls.target.copy(camera.position).addScaledVector(forward, distance);
  } else {
    camera.fov = number('fov', 50);
    controls.target.copy(center);
    camera.position.copy(center).add(new THREE.Vector3(0, 0.2 * size, 1.1 * size));
  }
  camera.near = size * 1e-3;
  camera.far = size * 100;
  camera.aspect = window.innerWidth / window.innerHeight;
  camera.updateProjectionMatrix();
  camera.lookAt(controls.target);
  controls.update();
}

/** A strength slider and a tint picker per light group (the file's Light Groups), if it has any. */
function addMixer(groups, changed) {
  for (const [name, group] of groups) {
    const row = document.createElement('label');
    row.textContent = name;
    const strength = document.createElement('input');
    Object.assign(strength, { type: 'range', min: '0', max: '2', step: '0.01', value: String(group.strength) });
    strength.dataset.group = name;
    const tint = document.createElement('input');
    const hex = (v) => Math.round(Math.min(1, Math.max(0, v)) ** (1 / 2.2) * 255).toString(16).padStart(2, '0');
    Object.assign(tint, { type: 'color', value: `#${group.tint.map(hex).join('')}` });
    strength.addEventListener('input', () => { group.strength = Number(strength.value); changed(); });
    tint.addEventListener('input', () => {
      group.tint = [1, 3, 5].map((k) => (parseInt(tint.value.slice(k, k + 2), 16) / 255) ** 2.2);
      changed();
    });
    row.append(strength, tint);
    panel.append(row);
  }
}

async function main() {
  const file = params.get('file');
  if (!file) throw new Error('no file: open this page with ?file=URL of a .glb');
  if (params.get('ui') === '0') panel.hidden = true;
  status.textContent = `loading ${file}`;
  const gltf = await new GLTFLoader().loadAsync(file);
  const { count, textures, groups } = await applyLightmaps(gltf);
  for (const item of (params.get('mix') || '').split(',').filter(Boolean)) {
    const [name, value] = item.split(':');
    if (!groups.has(name)) throw new Error(`mix: no light group ${name} in the file (it has: ${[...groups.keys()]})`);
    const strength = Number(value);
    if (!Number.isFinite(strength) || strength < 0) throw new Error(`mix: ${item}: expected GROUP:STRENGTH >= 0`);
    groups.get(name).strength = strength;
  }
  mixLayers(textures, groups);
  addMixer(groups, () => { mixLayers(textures, groups); render(); });
  scene.add(gltf.scene);
  placeCamera(gltf);
  slider.addEventListener('input', () => setExposure(Number(slider.value)));
  controls.addEventListener('change', render);
  window.addEventListener('resize', () => {
    camera.aspect = window.innerWidth / window.innerHeight;
    camera.updateProjectionMatrix();
    renderer.setSize(window.innerWidth, window.innerHeight);
    render();
  });
  setExposure(number('exposure', 0));
  // One pixel read back: the first frame is drawn, not just queued, when the time is taken.
  const gl = renderer.getContext();
  gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, new Uint8Array(4));
  window.__photonlmFirstFrameMs = performance.now();
  status.textContent = `${file.split('/').pop()}: ${count} material${count === 1 ? '' : 's'} with lightmaps`;
  window.__photonlmReady = true;
}

main().catch((error) => {
  status.textContent = `error: ${error.message}`;
  panel.hidden = false;
  window.__photonlmError = String(error && error.stack || error);
  console.error(error);
});
