// Repertoire's replay viewer: draws a recording (see crates/scenes/src/record.rs) with three.js.
// Everything it needs is inlined in the page: three.js's two module files as text (loaded
// through blob URLs, since one imports the other), the recording as base64 columns.

const hook = (window.__replay = { ready: false, frame: 0, frames: 0, playing: false, drawn: 0 });

function fail(message) {
  const box = document.getElementById('error');
  box.hidden = false;
  box.textContent = message;
  throw new Error(message);
}

async function loadThree() {
  const text = (id) => document.getElementById(id).textContent;
  const url = (code) => URL.createObjectURL(new Blob([code], { type: 'text/javascript' }));
  const core = url(text('three-core'));
  const module = text('three-module').split("'./three.core.js'").join(JSON.stringify(core));
  return import(url(module));
}

function decode(b64, Type) {
  const bin = atob(b64);
  const bytes = new Uint8Array(bin.length);
  for (let i = 0; i < bin.length; i++) bytes[i] = bin.charCodeAt(i);
  return new Type(bytes.buffer);
}

const THREE = await loadThree().catch((e) => fail('could not load the inlined three.js: ' + e));
const data = JSON.parse(document.getElementById('recording').textContent);
const H = data.header;
const N = H.frames;
if (N < 1) fail('the recording has no frames');
const NB = H.bodies.length;
const P = data.pose;
const time = decode(data.time, Float32Array);
const poses = decode(data.poses, Float32Array);
const ghostPoses = decode(data.ghost, Float32Array);
const skill = decode(data.skill, Int32Array);
const phase = decode(data.phase, Float32Array);
const terms = decode(data.terms, Float32Array);
const flags = decode(data.flags, Uint8Array);
// The fall test's verdict per frame (0 none, else a cause code 1..4; older pages: the flag).
const fallCode = data.fall ? decode(data.fall, Uint8Array) : flags.map((v) => v & 1);
// Which prop the pelvis rests on (its key geom: a seat, a pedestal's top, a box), by name.
const pelvisOn = data.pelvis_on ? decode(data.pelvis_on, Uint8Array) : null;
const pelvisLabel = (f) => {
  const p = pelvisOn ? pelvisOn[f] : 0;
  return p && H.props[p - 1] ? `pelvis on ${H.props[p - 1][0]}` : 'pelvis on a prop';
};
hook.fall_frames = fallCode.reduce((n, c) => n + (c ? 1 : 0), 0);
// Which feet touch the floor per frame (bit 0 left, bit 1 right); null for recordings made
// before it was recorded (format 1).
const feet = data.feet ? decode(data.feet, Uint8Array) : null;
hook.foot_frames = feet ? [0, 1].map((s) => feet.reduce((n, v) => n + ((v >> s) & 1), 0)) : null;
const feetText = (f) => (feet ? `   feet ${feet[f] & 1 ? 'L' : '·'} ${feet[f] & 2 ? 'R' : '·'}` : '');
const fallCause = (f) => (fallCode[f] ? (data.fall_causes || [])[fallCode[f] - 1] || 'fall' : '');
const NT = H.terms.length;
const character = H.bodies.map((b, i) => (b.character ? i : -1)).filter((i) => i >= 0);
const hasGhost = H.ghost !== null && ghostPoses.length === N * character.length * P;

// Scene, z up as in MuJoCo.
THREE.Object3D.DEFAULT_UP.set(0, 0, 1);
const view = document.getElementById('view');
const renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
renderer.setPixelRatio(Math.min(window.devicePixelRatio || 1, 2));
view.appendChild(renderer.domElement);
const scene = new THREE.Scene();
scene.background = new THREE.Color(0x1d2126);
scene.fog = new THREE.Fog(0x1d2126, 12, 40);
const camera = new THREE.PerspectiveCamera(45, 1, 0.05, 200);
camera.up.set(0, 0, 1);
scene.add(new THREE.HemisphereLight(0xdde8ff, 0x3a3430, 1.6));
const sun = new THREE.DirectionalLight(0xffffff, 1.8);
sun.position.set(3, -4, 8);
scene.add(sun);

function rgbaColor(rgba) {
  return new THREE.Color().setRGB(rgba[0], rgba[1], rgba[2], THREE.SRGBColorSpace);
}

function geometryOf(g) {
  const s = g.size;
  switch (g.shape) {
    case 'Sphere':
      return new THREE.SphereGeometry(s[0], 20, 14);
    case 'Capsule':
      return new THREE.CapsuleGeometry(s[0], 2 * s[1], 6, 16).rotateX(Math.PI / 2);
    case 'Cylinder':
      return new THREE.CylinderGeometry(s[0], s[0], 2 * s[1], 20).rotateX(Math.PI / 2);
    case 'Ellipsoid':
      return new THREE.SphereGeometry(1, 20, 14).scale(s[0], s[1], s[2]);
    case 'Box':
    case 'Other':
      return new THREE.BoxGeometry(2 * s[0], 2 * s[1], 2 * s[2]);
    default:
      return null;
  }
}

function floor(g) {
  const half = g.size[0] > 0 ? g.size[0] : 30;
  const group = new THREE.Group();
  const plane = new THREE.Mesh(
    new THREE.PlaneGeometry(2 * half, 2 * half),
    new THREE.MeshStandardMaterial({ color: 0x3a4048, roughness: 0.95 }),
  );
  group.add(plane);
  const grid = new THREE.GridHelper(2 * half, Math.round(4 * half), 0x59626c, 0x4a525b);
  grid.rotation.x = Math.PI / 2;
  grid.position.z = 0.001;
  group.add(grid);
  return group;
}

function setPose(obj, x, y, z, qw, qx, qy, qz) {
  obj.position.set(x, y, z);
  obj.quaternion.set(qx, qy, qz, qw);
}

// One group per body, moved each frame; geoms are its children at their local poses.
function buildBodies(filter, material) {
  const groups = H.bodies.map(() => null);
  H.geoms.forEach((g) => {
    if (g.body === null) {
      if (material) return;
      const obj = g.shape === 'Plane' ? floor(g) : new THREE.Mesh(geometryOf(g), new THREE.MeshStandardMaterial({ color: rgbaColor(g.rgba) }));
      setPose(obj, ...g.pos, ...g.quat);
      scene.add(obj);
      return;
    }
    if (!filter(g.body) || g.rgba[3] === 0) return;
    const geo = geometryOf(g);
    if (!geo) return;
    if (!groups[g.body]) {
      groups[g.body] = new THREE.Group();
      scene.add(groups[g.body]);
    }
    const mat = material || new THREE.MeshStandardMaterial({
      color: rgbaColor(g.rgba), roughness: 0.7, transparent: g.rgba[3] < 1, opacity: g.rgba[3],
    });
    const mesh = new THREE.Mesh(geo, mat);
    setPose(mesh, ...g.pos, ...g.quat);
    groups[g.body].add(mesh);
  });
  return groups;
}

const bodies = buildBodies(() => true, null);
const ghostMaterial = new THREE.MeshStandardMaterial({
  color: 0x7fb8ff, transparent: true, opacity: 0.35, depthWrite: false, roughness: 0.5,
});
const ghostBodies = hasGhost ? buildBodies((b) => H.bodies[b].character, ghostMaterial) : [];

// Controls.
const ui = (id) => document.getElementById(id);
const playButton = ui('play');
const scrub = ui('scrub');
scrub.max = String(N - 1);
let playing = true;
let cursor = 0; // frame position, fractional while playing
let speed = 1;
let ghostMode = 'beside';
let follow = true;
function setPlaying(p) {
  // Play from the start again once the end was reached.
  if (p && cursor >= N - 1) cursor = 0;
  playing = p;
  playButton.textContent = p ? '❚❚' : '▶';
  hook.playing = p;
}
playButton.onclick = () => setPlaying(!playing);
scrub.oninput = () => { cursor = Number(scrub.value); setPlaying(false); };
ui('speed').onchange = (e) => { speed = Number(e.target.value); };
ui('ghostmode').onchange = (e) => { ghostMode = e.target.value; };
ui('follow').onchange = (e) => { follow = e.target.checked; };
if (!hasGhost) ui('ghostmode').disabled = true;
window.addEventListener('keydown', (e) => {
  if (e.key === ' ') { setPlaying(!playing); e.preventDefault(); }
  if (e.key === 'ArrowRight') { setPlaying(false); cursor = Math.min(N - 1, Math.floor(cursor) + 1); }
  if (e.key === 'ArrowLeft') { setPlaying(false); cursor = Math.max(0, Math.floor(cursor) - 1); }
});

// A hand-written orbit: drag to turn, wheel to zoom, around a target that follows the pelvis.
// Start beside the character's right shoulder, 60° off its heading at the first frame.
const startYaw = (() => {
  const k = H.root * P;
  const [w, x, y, z] = [poses[k + 3], poses[k + 4], poses[k + 5], poses[k + 6]];
  return Math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z));
})();
const orbit = { azimuth: startYaw - Math.PI / 3, elevation: 0.3, distance: 4.2, target: new THREE.Vector3(0, 0, 0.9) };
// Fixed views, set from the character's heading at the first frame (the orbit still follows the
// pelvis): its right side, its front, from above.
const VIEWS = {
  side: { azimuth: startYaw - Math.PI / 2, elevation: 0.12, distance: 4.2 },
  front: { azimuth: startYaw, elevation: 0.12, distance: 4.2 },
  top: { azimuth: startYaw - Math.PI / 2, elevation: 1.45, distance: 5.0 },
};
function setView(name) {
  const v = VIEWS[name];
  if (v) Object.assign(orbit, v);
}
ui('viewpreset').onchange = (e) => setView(e.target.value);
let drag = null;
renderer.domElement.addEventListener('pointerdown', (e) => { drag = { x: e.clientX, y: e.clientY }; });
window.addEventListener('pointerup', () => { drag = null; });
window.addEventListener('pointermove', (e) => {
  if (!drag) return;
  orbit.azimuth -= (e.clientX - drag.x) * 0.008;
  orbit.elevation = Math.min(1.5, Math.max(-0.2, orbit.elevation + (e.clientY - drag.y) * 0.008));
  drag = { x: e.clientX, y: e.clientY };
});
renderer.domElement.addEventListener('wheel', (e) => {
  orbit.distance = Math.min(40, Math.max(0.8, orbit.distance * Math.exp(e.deltaY * 0.001)));
  e.preventDefault();
}, { passive: false });

// Timeline strip coloured by active skill.
// No red or pink among the skills: red is the fall's alone.
const palette = ['#4e79a7', '#f28e2b', '#59a14f', '#b07aa1', '#76b7b2', '#edc948', '#9c755f', '#bab0ac', '#86bcb6'];
// Half the width of the slider's thumb: the slider's track starts and ends that far in.
const THUMB_INSET = 8;
const skillColor = (s) => (s < 0 ? '#555b62' : palette[s % palette.length]);
const strip = ui('strip');
function drawStrip(frame) {
  const w = strip.clientWidth, h = strip.clientHeight;
  if (strip.width !== w) strip.width = w;
  if (strip.height !== h) strip.height = h;
  const ctx = strip.getContext('2d');
  ctx.clearRect(0, 0, w, h);
  const span = Math.max(1, w - 2 * THUMB_INSET);
  for (let x = 0; x < w; x++) {
    const f = Math.min(N - 1, Math.max(0, Math.floor(((x - THUMB_INSET) / span) * N)));
    ctx.fillStyle = skillColor(skill[f]);
    ctx.fillRect(x, 0, 1, h - 4);
    // A gait diagram over the skill colours: the left foot's floor contact in the top lane,
    // the right foot's in the lane below.
    if (feet) {
      ctx.fillStyle = '#f4f4f4';
      if (feet[f] & 1) ctx.fillRect(x, 1, 1, 2);
      if (feet[f] & 2) ctx.fillRect(x, 4, 1, 2);
    }
    // A fall covers the lower half of the strip in hatched red from the frame it counted on, so
    // it reads apart from any skill colour; seat contact is the green line under the strip.
    if (fallCode[f]) {
      ctx.fillStyle = (x >> 2) % 2 ? '#ff2020' : '#ffffff';
      ctx.fillRect(x, Math.floor(h / 2), 1, h - Math.floor(h / 2));
    } else {
      ctx.fillStyle = flags[f] & 2 ? '#7cff7c' : '#262b31';
      ctx.fillRect(x, h - 3, 1, 3);
    }
  }
  const cx = THUMB_INSET + (frame / Math.max(1, N - 1)) * (span - 1);
  ctx.fillStyle = '#ffffff';
  ctx.fillRect(Math.round(cx) - 1, 0, 3, h);
}
strip.addEventListener('pointerdown', (e) => {
  const r = strip.getBoundingClientRect();
  const at = (e.clientX - r.left - THUMB_INSET) / Math.max(1, r.width - 2 * THUMB_INSET);
  cursor = Math.min(N - 1, Math.max(0, Math.round(at * (N - 1))));
  setPlaying(false);
});
ui('legend').innerHTML = H.skills.length
  ? H.skills.map((s, i) => `<span><i style="background:${skillColor(i)}"></i>${s.replace(/</g, '&lt;')}</span>`).join('')
  : '<span>no skill annotation</span>';

// Each term's bar is its size against the largest it reaches in this recording (a distance of
// 2.95 m is not a "full" bar unless nothing in the episode is farther); negative values in orange.
const termScale = H.terms.map((_, k) => {
  let m = 0;
  for (let f = 0; f < N; f++) m = Math.max(m, Math.abs(terms[f * NT + k]));
  return m > 0 ? m : 1;
});
const termRows = H.terms.map((name) => {
  const tr = document.createElement('tr');
  tr.innerHTML = `<td></td><td class="v"></td><td><span class="bar"></span></td>`;
  tr.children[0].textContent = name;
  ui('terms').appendChild(tr);
  return tr;
});

// Ghost placement: beside = 1 m to the left of where the reference stands.
const ghostOffset = new THREE.Vector3();
// A footprint on the floor under each foot while it touches the floor.
const footprints = [0, 1].map(() => {
  const m = new THREE.Mesh(
    new THREE.CircleGeometry(0.07, 24),
    new THREE.MeshBasicMaterial({ color: 0x7cff7c, transparent: true, opacity: 0.55, depthWrite: false }),
  );
  m.visible = false;
  scene.add(m);
  return m;
});
function placeFeet(f) {
  footprints.forEach((m, s) => {
    const b = H.feet ? H.feet[s] : -1;
    m.visible = !!feet && b >= 0 && (feet[f] >> s) % 2 === 1;
    if (m.visible) {
      const k = (f * NB + b) * P;
      m.position.set(poses[k], poses[k + 1], 0.003);
    }
  });
}
function placeFrame(f) {
  placeFeet(f);
  for (let b = 0; b < NB; b++) {
    const g = bodies[b];
    if (!g) continue;
    const k = (f * NB + b) * P;
    setPose(g, poses[k], poses[k + 1], poses[k + 2], poses[k + 3], poses[k + 4], poses[k + 5], poses[k + 6]);
  }
  if (hasGhost) {
    const root = character.indexOf(H.root);
    ghostOffset.set(0, 0, 0);
    if (ghostMode === 'overlay' && root >= 0) {
      // On the body: the reference's pelvis moved onto the character's, so the pose is compared
      // where the character is, not where the clip was.
      const kb = (f * NB + H.root) * P, kg = (f * character.length + root) * P;
      ghostOffset.set(poses[kb] - ghostPoses[kg], poses[kb + 1] - ghostPoses[kg + 1], 0);
    }
    if (ghostMode === 'beside' && root >= 0) {
      const k = (f * character.length + root) * P;
      const q = new THREE.Quaternion(ghostPoses[k + 4], ghostPoses[k + 5], ghostPoses[k + 6], ghostPoses[k + 3]);
      const left = new THREE.Vector3(0, 1, 0).applyQuaternion(q);
      left.z = 0;
      if (left.lengthSq() > 1e-6) ghostOffset.copy(left.normalize());
    }
    character.forEach((b, i) => {
      const g = ghostBodies[b];
      if (!g) return;
      g.visible = ghostMode !== 'off';
      const k = (f * character.length + i) * P;
      setPose(g, ghostPoses[k] + ghostOffset.x, ghostPoses[k + 1] + ghostOffset.y, ghostPoses[k + 2],
        ghostPoses[k + 3], ghostPoses[k + 4], ghostPoses[k + 5], ghostPoses[k + 6]);
    });
  }
}

function overlay(f) {
  const s = skill[f];
  const fl = flags[f];
  const contacts = [fallCode[f] ? `FALLEN (${fallCause(f)})` : '', fl & 2 ? pelvisLabel(f) : '', fl & 4 ? 'hand on prop' : '', fl & 8 ? 'touching a prop' : '']
    .filter(Boolean).join(', ') || '—';
  ui('info').textContent =
    `t ${time[f].toFixed(2)} s   frame ${f + 1}/${N}\n` +
    `skill ${s < 0 ? '—' : H.skills[s]}   ${H.phase || 'phase'} ${phase[f].toFixed(0)}\n` +
    `contacts ${contacts}${feetText(f)}` + (hasGhost ? `\nghost: ${H.ghost}` : '');
  termRows.forEach((tr, k) => {
    const v = terms[f * NT + k];
    tr.children[1].textContent = v.toFixed(3);
    const bar = tr.querySelector('.bar');
    bar.style.width = `${Math.min(1, Math.abs(v) / termScale[k]) * 60}px`;
    bar.style.background = v < 0 ? '#f28e2b' : '#6cb0ff';
  });
  ui('clock').textContent = `${time[f].toFixed(2)} / ${time[N - 1].toFixed(2)} s`;
}

function resize() {
  const w = view.clientWidth, h = view.clientHeight;
  renderer.setSize(w, h, false);
  camera.aspect = w / Math.max(1, h);
  camera.updateProjectionMatrix();
}
window.addEventListener('resize', resize);
resize();

const rootTarget = new THREE.Vector3();
// The pelvis of frame `f` (at least 0.5 m up, so a fallen body stays in view) into `v`.
function pelvisAt(f, v) {
  const k = (f * NB + H.root) * P;
  v.set(poses[k], poses[k + 1], Math.max(0.5, poses[k + 2]));
}
// The camera on the orbit around its target.
function aimCamera() {
  const ce = Math.cos(orbit.elevation);
  camera.position.set(
    orbit.target.x + orbit.distance * ce * Math.cos(orbit.azimuth),
    orbit.target.y + orbit.distance * ce * Math.sin(orbit.azimuth),
    orbit.target.z + orbit.distance * Math.sin(orbit.elevation),
  );
  camera.lookAt(orbit.target);
}
let last = performance.now();
let shown = -1;
function frameLoop(now) {
  const dt = Math.min(0.1, (now - last) / 1000);
  last = now;
  // An episode plays once and stops on its last frame (a fall stays in view); play restarts it.
  if (playing) {
    cursor += dt * speed * H.control_hz;
    if (cursor >= N - 1) { cursor = N - 1; setPlaying(false); }
  }
  const f = Math.min(N - 1, Math.max(0, Math.floor(cursor)));
  placeFrame(f);
  if (f !== shown) {
    overlay(f);
    scrub.value = String(f);
    shown = f;
  }
  drawStrip(f);
  pelvisAt(f, rootTarget);
  // Ease towards the pelvis at the same pace whatever the frame rate; jump on the first draw.
  if (follow) orbit.target.lerp(rootTarget, hook.drawn > 0 ? 1 - Math.exp(-8 * dt) : 1);
  aimCamera();
  renderer.render(scene, camera);
  hook.frame = f;
  hook.frames = N;
  hook.drawn += 1;
  requestAnimationFrame(frameLoop);
}
// A contact sheet of the recording (`repertoire replay FILE --filmstrip OUT.png`): `count`
// frames evenly spaced from the first to the last, each drawn from `view` around the pelvis of
// its own frame, `columns` to a row, each captioned with its time and skill (and a fall).
// Returns the sheet as a PNG data URL.
hook.filmstrip = (count, view, columns, tileW, tileH) => {
  setPlaying(false);
  if (!VIEWS[view]) throw new Error(`unknown view ${view}`);
  setView(view);
  const n = Math.max(1, Math.min(count, N));
  const cols = Math.max(1, Math.min(columns, n));
  const rows = Math.ceil(n / cols);
  const caption = 22;
  const sheet = document.createElement('canvas');
  sheet.width = cols * tileW;
  sheet.height = rows * (tileH + caption);
  const ctx = sheet.getContext('2d');
  ctx.fillStyle = '#1b1f24';
  ctx.fillRect(0, 0, sheet.width, sheet.height);
  renderer.setPixelRatio(1);
  renderer.setSize(tileW, tileH, false);
  camera.aspect = tileW / tileH;
  camera.updateProjectionMatrix();
  for (let i = 0; i < n; i++) {
    const f = n === 1 ? 0 : Math.round((i * (N - 1)) / (n - 1));
    placeFrame(f);
    pelvisAt(f, orbit.target);
    aimCamera();
    renderer.render(scene, camera);
    const x = (i % cols) * tileW, y = Math.floor(i / cols) * (tileH + caption);
    ctx.drawImage(renderer.domElement, x, y, tileW, tileH);
    ctx.fillStyle = fallCode[f] ? '#ff5050' : '#e8e8e8';
    ctx.font = '14px sans-serif';
    const s = skill[f] < 0 ? '' : `  ${H.skills[skill[f]]}`;
    const fell = fallCode[f] ? `  FALLEN (${fallCause(f)})` : '';
    ctx.fillText(`t ${time[f].toFixed(2)} s${s}${fell}`, x + 6, y + tileH + 16);
  }
  renderer.setPixelRatio(Math.min(window.devicePixelRatio || 1, 2));
  resize();
  return sheet.toDataURL('image/png');
};

setPlaying(true);
hook.ready = true;
requestAnimationFrame(frameLoop);
