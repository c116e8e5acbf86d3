// Cerberus reconstruction viewer: one card per image; the page embeds the GLBs (base64) and three.js
// (an import map of data: URLs), so it works from file:// with no fetch. Written by cerberus_core.eval.viewer.
// One WebGL renderer draws every card into the card's own 2D canvas (no per-card WebGL context limit);
// each card renders only when its view, model, parts or light change.
import * as THREE from 'three';
import { OrbitControls } from 'cerberus-three/examples/jsm/controls/OrbitControls.js';
import { GLTFLoader } from 'cerberus-three/examples/jsm/loaders/GLTFLoader.js';

const DATA = JSON.parse(document.getElementById('cerberus-viewer-data').textContent);
const SIZE = DATA.canvas_size;  // CSS pixels of each 3D view
const DPR = Math.min(window.devicePixelRatio || 1, 2);
const HASH = new URLSearchParams(window.location.hash.slice(1));  // e.g. #model=ground_truth&light=new
const viewer = window.cerberusViewer;  // created by the page's first script (it also collects errors)
viewer.cards = [];

function publish() {  // a machine-readable summary in the DOM (tests read it with --dump-dom)
  viewer.meshCount = viewer.cards.reduce((n, c) => n + (c.meshCounts.reconstruction || 0), 0);
  const out = { ready: viewer.ready, errors: viewer.errors, meshCount: viewer.meshCount,
                cards: viewer.cards.map((c) => {
                  const r = c.canvas.getBoundingClientRect();
                  return { name: c.entry.name, meshCounts: c.meshCounts, shown: c.current, light: c.lightSelect.value,
                           iou: c.entry.iou, parts: [...c.parts.querySelectorAll('.part-name')].map((e) => e.textContent),
                           canvas: { x: r.left + window.scrollX, y: r.top + window.scrollY, width: r.width, height: r.height } };
                }) };
  document.getElementById('viewer-status').textContent = JSON.stringify(out);
  document.body.dataset.viewer = viewer.ready ? (viewer.errors.length ? 'error' : 'ready') : 'loading';
}

const renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
renderer.setPixelRatio(1);
renderer.setSize(SIZE * DPR, SIZE * DPR, false);

function base64ToBuffer(b64) {
  const bin = atob(b64);
  const bytes = new Uint8Array(bin.length);
  for (let i = 0; i < bin.length; i++) bytes[i] = bin.charCodeAt(i);
  return bytes.buffer;
}

function el(tag, attrs = {}, ...children) {
  const e = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs)) {
    if (k === 'class') e.className = v; else if (k in e) e[k] = v; else e.setAttribute(k, v);
  }
  e.append(...children);
  return e;
}

const deg = THREE.MathUtils.degToRad;
const dirFromAngles = (az, el) => new THREE.Vector3(Math.cos(deg(el)) * Math.sin(deg(az)), Math.sin(deg(el)),
                                                    Math.cos(deg(el)) * Math.cos(deg(az)));
function anglesFromDir(d) {
  const v = new THREE.Vector3(...d).normalize();
  return [THREE.MathUtils.radToDeg(Math.atan2(v.x, v.z)), THREE.MathUtils.radToDeg(Math.asin(v.y))];
}

// A learned part's toggle says its label where the card or the evaluation knows it ("head (part_05)"); the
// ground truth's nodes are named by their semantic parts already.
function partName(modelKey, node) {
  const label = DATA.labelled_models.includes(modelKey) ? DATA.part_labels[node] : undefined;
  return label ? `${label} (${node})` : node;
}

class Card {
  constructor(entry, section) {
    this.entry = entry;
    this.meshCounts = {};
    this.models = {};  // key -> THREE.Group
    this.scene = new THREE.Scene();
    this.scene.background = new THREE.Color(...DATA.background);
    const cam = entry.camera || DATA.default_camera;
    this.camera = new THREE.PerspectiveCamera(cam.fov_y, 1, 0.05, 100);
    this.home = dirFromAngles(cam.azimuth, cam.elevation).multiplyScalar(cam.distance);
    this.ambient = new THREE.AmbientLight(0xffffff, 1);
    this.sun = new THREE.DirectionalLight(0xffffff, 1);
    this.camera.add(this.sun, this.sun.target);  // the light is given in the camera's frame
    this.scene.add(this.ambient, this.camera);

    const view = section.querySelector('.view');
    this.canvas = el('canvas', { class: 'gl', width: SIZE * DPR, height: SIZE * DPR,
                                 title: 'drag: orbit, wheel: zoom, right-drag: pan' });
    this.canvas.style.width = this.canvas.style.height = `${SIZE}px`;
    this.ctx = this.canvas.getContext('2d');
    this.controls = new OrbitControls(this.camera, this.canvas);
    this.controls.addEventListener('change', () => this.draw());
    this.resetView();

    const wanted = entry.models.find((m) => m.key === HASH.get('model'));
    this.first = (wanted || entry.models[0]).key;
    const models = entry.models.map((m) => el('label', {},
      el('input', { type: 'radio', name: `model-${entry.index}`, value: m.key, checked: m.key === this.first,
                    onchange: () => this.show(m.key) }), ` ${m.label}`));
    const presets = Object.entries(DATA.lights).map(([key, l]) =>
      el('option', { value: key, textContent: l.label }));
    this.lightSelect = el('select', { onchange: () => this.setLight(this.lightSelect.value) }, ...presets);
    this.lightAz = el('input', { type: 'range', min: -180, max: 180, step: 1, oninput: () => this.lightChanged() });
    this.lightEl = el('input', { type: 'range', min: -89, max: 89, step: 1, oninput: () => this.lightChanged() });
    this.parts = el('div', { class: 'parts' });
    this.message = el('p', { class: 'message' });
    view.append(
      this.canvas,
      el('div', { class: 'controls' },
        el('div', { class: 'models' }, ...models),
        el('div', { class: 'light' }, el('label', {}, 'Light ', this.lightSelect)),
        el('div', { class: 'light' }, 'direction ', el('label', {}, 'azimuth ', this.lightAz),
          el('label', {}, ' elevation ', this.lightEl)),
        el('div', { class: 'buttons' },
          el('button', { type: 'button', textContent: 'Reset view', onclick: () => this.resetView() }),
          el('button', { type: 'button', textContent: 'All parts', onclick: () => this.setAll(true) }),
          el('button', { type: 'button', textContent: 'No parts', onclick: () => this.setAll(false) })),
        this.parts, this.message));
    this.lightSelect.value = HASH.get('light') in DATA.lights ? HASH.get('light') : Object.keys(DATA.lights)[0];
    this.setLight(this.lightSelect.value);
  }

  async load() {
    const loader = new GLTFLoader();
    for (const m of this.entry.models) {
      const gltf = await loader.parseAsync(base64ToBuffer(m.glb), '');
      const meshes = [];
      gltf.scene.traverse((o) => { if (o.isMesh) meshes.push(o); });
      for (const mesh of meshes) {
        if (!mesh.geometry.attributes.normal) mesh.geometry.computeVertexNormals();  // smooth shading
        for (const mat of [mesh.material].flat()) {
          mat.flatShading = false;
          mat.needsUpdate = true;
          // Part colours are display (sRGB) values, as in the PNG pictures: treat the glTF factor so.
          mat.color.convertSRGBToLinear();
          mat.side = THREE.DoubleSide;
        }
      }
      this.meshCounts[m.key] = meshes.length;
      gltf.scene.visible = false;
      this.models[m.key] = gltf.scene;
      this.scene.add(gltf.scene);
    }
    this.show(this.first);
  }

  show(key) {
    this.current = key;
    for (const [k, g] of Object.entries(this.models)) g.visible = k === key;
    const meshes = [];
    this.models[key].traverse((o) => { if (o.isMesh) meshes.push(o); });
    // the glTF node's own name (three.js strips '.' and other characters from mesh.name: shin.L -> shinL)
    const nodeName = (mesh) => mesh.userData.name || mesh.name;
    meshes.sort((a, b) => nodeName(a).localeCompare(nodeName(b), undefined, { numeric: true }));
    this.parts.replaceChildren(...meshes.map((mesh) => el('label', { class: 'part' },
      el('input', { type: 'checkbox', checked: mesh.visible, onchange: (e) => { mesh.visible = e.target.checked; this.draw(); } }),
      el('span', { class: 'swatch', style: `background:#${mesh.material.color.getHexString(THREE.SRGBColorSpace)}` }),
      ' ', el('span', { class: 'part-name', textContent: partName(key, nodeName(mesh)) }))));
    this.draw();
  }

  setAll(on) {
    this.models[this.current].traverse((o) => { if (o.isMesh) o.visible = on; });
    this.parts.querySelectorAll('input').forEach((box) => { box.checked = on; });
    this.draw();
  }

  setLight(key) {
    const l = DATA.lights[key];
    const [az, elev] = anglesFromDir(l.direction);
    this.lightAz.value = Math.round(az);
    this.lightEl.value = Math.round(elev);
    this.ambient.intensity = Math.PI * l.ambient;  // three.js lights are physical: x pi gives the plain Lambert weights
    this.sun.intensity = Math.PI * l.diffuse;
    this.lightChanged();
  }

  lightChanged() {
    this.sun.position.copy(dirFromAngles(+this.lightAz.value, +this.lightEl.value));
    this.draw();
  }

  resetView() {
    this.camera.position.copy(this.home);
    this.controls.target.set(0, 0, 0);
    this.controls.update();
    this.draw();
  }

  draw() {
    if (!this.ctx) return;
    renderer.render(this.scene, this.camera);
    this.ctx.clearRect(0, 0, this.canvas.width, this.canvas.height);
    this.ctx.drawImage(renderer.domElement, 0, 0);
  }
}

async function main() {
  const sections = document.querySelectorAll('section.card');
  for (const entry of DATA.entries) {
    const card = new Card(entry, sections[entry.index]);
    viewer.cards.push(card);
    try {
      await card.load();
    } catch (err) {
      card.message.textContent = `could not load this reconstruction: ${err}`;
      viewer.errors.push(`${entry.name}: ${err}`);
    }
  }
}

main().catch((err) => viewer.errors.push(String(err))).finally(() => { viewer.ready = true; publish(); });
