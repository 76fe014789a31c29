// Echo's browser viewer: draws the scenes `echoctl view` serves at /scene.json (echo-scene's
// Scene as JSON: entities of spheres, capsules, line strips and labels in base_footprint,
// x forward, y left, z up, metres) with three.js, and keeps a status line that tests read.
import * as THREE from 'three';
import { OrbitControls } from 'three/addons/OrbitControls.js';

const view = document.getElementById('view');
const statusEl = document.getElementById('status');
const captionsEl = document.getElementById('captions');

const renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
renderer.setPixelRatio(window.devicePixelRatio || 1);
renderer.setSize(window.innerWidth, window.innerHeight);
view.appendChild(renderer.domElement);

const scene3 = new THREE.Scene();
scene3.background = new THREE.Color(0x1d2026);
const camera = new THREE.PerspectiveCamera(45, window.innerWidth / window.innerHeight, 0.05, 100);
camera.up.set(0, 0, 1);
camera.position.set(-1.2, -3.6, 2.4);
const controls = new OrbitControls(camera, renderer.domElement);
controls.target.set(0.9, 0, 0.8);
controls.update();

scene3.add(new THREE.HemisphereLight(0xffffff, 0x404040, 2.0));
const sun = new THREE.DirectionalLight(0xffffff, 1.5);
sun.position.set(-2, -3, 5);
scene3.add(sun);
const grid = new THREE.GridHelper(10, 20, 0x555c66, 0x3a3f47);
grid.rotation.x = Math.PI / 2; // the grid lies in the x–y floor (z up)
scene3.add(grid);
scene3.add(new THREE.AxesHelper(0.5));

// Shared unit geometries, scaled per primitive; one material per colour.
const unitSphere = new THREE.SphereGeometry(1, 16, 12);
const unitCylinder = new THREE.CylinderGeometry(1, 1, 1, 16, 1, true);
const materials = new Map();
function material(c) {
  const key = `${c.r.toFixed(3)},${c.g.toFixed(3)},${c.b.toFixed(3)},${c.a.toFixed(3)}`;
  let m = materials.get(key);
  if (!m) {
    m = new THREE.MeshStandardMaterial({
      color: new THREE.Color(c.r, c.g, c.b), roughness: 0.7, metalness: 0.0,
      transparent: c.a < 1, opacity: c.a, depthWrite: c.a >= 1,
    });
    materials.set(key, m);
  }
  return m;
}
function lineMaterial(c) {
  return new THREE.LineBasicMaterial({ color: new THREE.Color(c.r, c.g, c.b), transparent: c.a < 1, opacity: c.a });
}

const v3 = (p) => new THREE.Vector3(p[0], p[1], p[2]);
const yAxis = new THREE.Vector3(0, 1, 0);

function sphere(group, centre, radius, color) {
  const m = new THREE.Mesh(unitSphere, material(color));
  m.position.copy(v3(centre));
  m.scale.setScalar(radius);
  group.add(m);
}

function capsule(group, a, b, radius, color) {
  const pa = v3(a), pb = v3(b);
  const axis = new THREE.Vector3().subVectors(pb, pa);
  const len = axis.length();
  if (len > 1e-6) {
    const m = new THREE.Mesh(unitCylinder, material(color));
    m.position.copy(pa).addScaledVector(axis, 0.5);
    m.quaternion.setFromUnitVectors(yAxis, axis.clone().normalize());
    m.scale.set(radius, len, radius);
    group.add(m);
  }
  sphere(group, a, radius, color);
  sphere(group, b, radius, color);
}

function label(group, position, text, size, color) {
  const canvas = document.createElement('canvas');
  const ctx = canvas.getContext('2d');
  const px = 48;
  ctx.font = `${px}px sans-serif`;
  canvas.width = Math.max(1, Math.ceil(ctx.measureText(text).width) + 16);
  canvas.height = px + 16;
  ctx.font = `${px}px sans-serif`;
  ctx.fillStyle = `rgba(${Math.round(color.r * 255)},${Math.round(color.g * 255)},${Math.round(color.b * 255)},${color.a})`;
  ctx.textBaseline = 'middle';
  ctx.fillText(text, 8, canvas.height / 2);
  const tex = new THREE.CanvasTexture(canvas);
  const s = new THREE.Sprite(new THREE.SpriteMaterial({ map: tex, depthTest: false }));
  s.position.copy(v3(position));
  s.scale.set(size * canvas.width / canvas.height, size, 1);
  s.userData.dispose = () => { tex.dispose(); s.material.dispose(); };
  group.add(s);
}

// Entities by id: a group each, rebuilt when the entity changes.
const groups = new Map();
const state = { updates: 0, seq: 0, polls: 0, errors: 0, kinds: {}, primitives: {}, peak: {}, trackedId: null, partnerHead: null, firstPartnerHead: null, lastError: '' };
window.echoViewer = state;

function disposeGroup(g) {
  g.traverse((o) => {
    if (o.userData.dispose) o.userData.dispose();
    if (o.isLine) { o.geometry.dispose(); o.material.dispose(); }
  });
  scene3.remove(g);
}

function build(entity) {
  const g = new THREE.Group();
  for (const p of entity.primitives) {
    switch (p.kind) {
      case 'sphere': sphere(g, p.centre, p.radius, p.color); break;
      case 'capsule': capsule(g, p.a, p.b, p.radius, p.color); break;
      case 'line_strip': {
        if (p.points.length < 2) break;
        const geo = new THREE.BufferGeometry().setFromPoints(p.points.map(v3));
        g.add(new THREE.Line(geo, lineMaterial(p.color)));
        break;
      }
      case 'text': label(g, p.position, p.text, p.size, p.color); break;
    }
  }
  return g;
}

function apply(scene) {
  const seen = new Set();
  const kinds = {};
  const prims = {};
  for (const e of scene.entities) {
    seen.add(e.id);
    kinds[e.kind] = (kinds[e.kind] || 0) + 1;
    prims[e.kind] = (prims[e.kind] || 0) + e.primitives.length;
    const json = JSON.stringify(e.primitives);
    const old = groups.get(e.id);
    if (old && old.json === json) continue;
    if (old) disposeGroup(old.group);
    const group = build(e);
    scene3.add(group);
    groups.set(e.id, { group, json });
    // The tracked person: the partner once there is one, else the first person seen.
    if (e.kind === 'partner' || (e.kind === 'person' && !state.trackedId)) state.trackedId = e.id;
    if (e.id === state.trackedId) {
      // The head is the skeleton's one sphere.
      const s = e.primitives.find((p) => p.kind === 'sphere');
      if (s) {
        state.partnerHead = s.centre;
        if (!state.firstPartnerHead) state.firstPartnerHead = s.centre;
      }
    }
  }
  for (const [id, old] of groups) {
    if (!seen.has(id)) { disposeGroup(old.group); groups.delete(id); }
  }
  captionsEl.replaceChildren(...scene.captions.map((c) => {
    const d = document.createElement('div');
    d.textContent = c.text;
    // Captions are styled for a light background (the GIF): dark ones are lightened here.
    const lum = 0.2126 * c.color.r + 0.7152 * c.color.g + 0.0722 * c.color.b;
    d.style.color = lum < 0.45 ? '#d8dde3'
      : `rgb(${Math.round(c.color.r * 255)},${Math.round(c.color.g * 255)},${Math.round(c.color.b * 255)})`;
    return d;
  }));
  state.kinds = kinds;
  state.primitives = prims;
  for (const k of Object.keys(prims)) state.peak[k] = Math.max(state.peak[k] || 0, prims[k]);
  state.captions = scene.captions.map((c) => c.text);
  state.updates += 1;
}

function moved() {
  const a = state.firstPartnerHead, b = state.partnerHead;
  if (!a || !b) return 0;
  return Math.hypot(b[0] - a[0], b[1] - a[1], b[2] - a[2]);
}

function showStatus() {
  const kinds = Object.keys(state.kinds).sort().map((k) => `${k} ${state.kinds[k]}/${state.primitives[k]}`).join(', ');
  statusEl.textContent =
    `echo-viewer updates=${state.updates} seq=${state.seq} polls=${state.polls} errors=${state.errors}` +
    ` tracked=${state.trackedId || 'none'} person_moved_m=${moved().toFixed(3)} webgl=${renderer.getContext() ? 1 : 0}\n` +
    `entities (count/primitives): ${kinds || 'none yet'}\n` +
    `most primitives seen: ${Object.keys(state.peak).sort().map((k) => `${k} ${state.peak[k]}`).join(', ') || 'none yet'}`;
  statusEl.title = state.lastError ? `last error: ${state.lastError}` : '';
}

async function poll() {
  try {
    state.polls += 1;
    const r = await fetch('/scene.json', { cache: 'no-store' });
    state.lastError = '';
    if (r.status === 200) {
      const msg = await r.json();
      if (msg.seq !== state.seq) {
        state.seq = msg.seq;
        apply(msg.scene);
      }
    }
  } catch (e) {
    state.errors += 1;
    state.lastError = String(e);
  }
  showStatus();
  setTimeout(poll, 100);
}

window.addEventListener('resize', () => {
  camera.aspect = window.innerWidth / window.innerHeight;
  camera.updateProjectionMatrix();
  renderer.setSize(window.innerWidth, window.innerHeight);
});

function frame() {
  controls.update();
  renderer.render(scene3, camera);
  requestAnimationFrame(frame);
}
showStatus();
poll();
frame();
