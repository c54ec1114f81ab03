// nurbsreg inspect: the report's interactive parts. The page's numbers, histogram and table are
// static HTML written by the C++ program; this script sorts the table, draws the 3-D view of the
// coloured scan with three.js (embedded in the page as a base64 ES module: no network), shows a
// point's deviation and face on hover, and records in #selfcheck whether the view was drawn
// (for the tests, which open the page in headless Chromium).
const started = performance.now();
const $ = (id) => document.getElementById(id);
const check = $('selfcheck');
const report = JSON.parse($('report-data').textContent);
const view = JSON.parse($('view-data').textContent);

function decode(id) {
  const text = $(id).textContent.trim();
  const binary = atob(text);
  const bytes = new Uint8Array(binary.length);
  for (let i = 0; i < binary.length; ++i) bytes[i] = binary.charCodeAt(i);
  return bytes.buffer;
}

function fmt(d) { return (d >= 0 ? '+' : '') + d.toFixed(4); }

// ---- the face table: sort by a column (numbers by value, empty cells last) ----
const table = $('faces');
let sortState = { column: -1, ascending: true };
table.querySelectorAll('th').forEach((th, column) => {
  th.addEventListener('click', () => {
    const ascending = sortState.column === column ? !sortState.ascending : true;
    sortState = { column, ascending };
    const numeric = th.dataset.sort === 'num';
    const body = table.tBodies[0];
    const rows = Array.from(body.rows);
    const key = (row) => row.cells[column].dataset.value;
    rows.sort((a, b) => {
      const x = key(a), y = key(b);
      if (x === '' || y === '') return (x === '') - (y === '');
      const order = numeric ? Number(x) - Number(y) : x.localeCompare(y);
      return ascending ? order : -order;
    });
    rows.forEach((row) => body.appendChild(row));
    table.querySelectorAll('th').forEach((h) => h.removeAttribute('data-order'));
    th.dataset.order = ascending ? 'asc' : 'desc';
  });
});

// The worst faces first: by share inside the tolerance, ascending (faces without points last).
table.querySelectorAll('th')[9].click();

// ---- the legend (drawn from the colour map's own samples) ----
function drawLegend() {
  const ramp = new Uint8Array(decode('legend-ramp'));
  const [lo, hi] = view.limits, [bandLo, bandHi] = view.band;
  const canvas = document.createElement('canvas');
  const scale = window.devicePixelRatio || 1;
  const w = 210, h = 360;
  canvas.width = w * scale; canvas.height = h * scale;
  canvas.style.width = w + 'px'; canvas.style.height = h + 'px';
  const g = canvas.getContext('2d');
  g.scale(scale, scale);
  g.fillStyle = 'rgba(255,255,255,0.9)';
  g.fillRect(0, 0, w, h);
  g.fillStyle = '#222'; g.font = 'bold 13px sans-serif';
  g.fillText(`Signed deviation (${view.units})`, 10, 18);
  // The bar is linear in the deviation between the limits; the boxes above and below it hold
  // the saturated colours of everything beyond.
  const x = 14, top = 56, barH = 240, barW = 22, box = 14, gap = 8;
  const y = (d) => top + barH * (hi - d) / (hi - lo);
  const rgb = (k) => `rgb(${ramp[3 * k]},${ramp[3 * k + 1]},${ramp[3 * k + 2]})`;
  g.fillStyle = rgb(255); g.fillRect(x, top - gap - box, barW, box);
  g.fillStyle = rgb(0); g.fillRect(x, top + barH + gap, barW, box);
  for (let k = 0; k < barH; ++k) {
    const d = hi - (k + 0.5) / barH * (hi - lo);
    g.fillStyle = rgb(Math.min(255, Math.max(0, Math.round((d - lo) / (hi - lo) * 255))));
    g.fillRect(x, top + k, barW, 1.2);
  }
  g.strokeStyle = '#333'; g.strokeRect(x + 0.5, top + 0.5, barW - 1, barH - 1);
  g.font = '12px sans-serif'; g.fillStyle = '#222';
  const tick = (d, label, bold) => {
    g.beginPath(); g.moveTo(x + barW, y(d)); g.lineTo(x + barW + 6, y(d)); g.stroke();
    g.font = (bold ? 'bold ' : '') + '12px sans-serif';
    g.fillText(label, x + barW + 9, y(d) + 4);
  };
  const s = (d) => (d === 0 ? '' : d > 0 ? '+' : '') + Number(d.toPrecision(3));
  g.fillText('> ' + s(hi), x + barW + 9, top - gap - box / 2 + 4);
  g.fillText('< ' + s(lo), x + barW + 9, top + barH + gap + box / 2 + 4);
  tick(hi, s(hi)); tick(lo, s(lo));
  tick(bandHi, s(bandHi) + '  upper tol.', true);
  tick(bandLo, s(bandLo) + '  lower tol.', true);
  if (bandLo < 0 && bandHi > 0 && y(bandLo) - y(bandHi) > 36) tick(0, '0');
  g.font = '11px sans-serif'; g.fillStyle = '#555';
  g.fillText(`scale ${view.scheme}, saturated beyond`, 10, h - 26);
  g.fillText(`[${s(lo)}, ${s(hi)}] ${view.units}`, 10, h - 12);
  $('legend').appendChild(canvas);
}
drawLegend();

// ---- the 3-D view ----
const THREE = await import('data:text/javascript;base64,' + $('three-module').textContent.trim());
const container = $('viewer');
const canvas = $('canvas');
const renderer = new THREE.WebGLRenderer({ canvas, antialias: true, preserveDrawingBuffer: true });
// The colours are the colour map's sRGB bytes: shown as they are, no colour management.
renderer.outputColorSpace = THREE.LinearSRGBColorSpace;
THREE.ColorManagement.enabled = false;
renderer.setPixelRatio(window.devicePixelRatio || 1);
const background = new THREE.Color(0xf3f4f6);
renderer.setClearColor(background);
const scene = new THREE.Scene();

const positions = new Float32Array(decode('points-position'));
const colours = new Uint8Array(decode('points-colour'));
const deviation = new Float32Array(decode('points-deviation'));
const faces = new Int32Array(decode('points-face'));
const count = deviation.length;
const geometry = new THREE.BufferGeometry();
geometry.setAttribute('position', new THREE.BufferAttribute(positions, 3));
const shown = new Uint8Array(colours);
const colourAttribute = new THREE.BufferAttribute(shown, 3, true);
geometry.setAttribute('color', colourAttribute);
geometry.computeBoundingSphere();
const material = new THREE.PointsMaterial({ size: 2, vertexColors: true, sizeAttenuation: false });
const points = new THREE.Points(geometry, material);
scene.add(points);

const meshPositions = new Float32Array(decode('mesh-position'));
const meshIndex = new Uint32Array(decode('mesh-index'));
let model = null;
if (meshIndex.length > 0) {
  const g = new THREE.BufferGeometry();
  g.setAttribute('position', new THREE.BufferAttribute(meshPositions, 3));
  g.setIndex(new THREE.BufferAttribute(meshIndex, 1));
  g.computeVertexNormals();
  model = new THREE.Mesh(g, new THREE.MeshLambertMaterial({
    color: 0xb4b8c0, side: THREE.DoubleSide,
    // Behind the points that lie on it.
    polygonOffset: true, polygonOffsetFactor: 2, polygonOffsetUnits: 2 }));
  scene.add(model);
}
// three.js lights are physical (Lambert divides by pi): these give about 0.45 ambient and 0.8
// direct light of the grey.
scene.add(new THREE.AmbientLight(0xffffff, 1.4));
const camera = new THREE.OrthographicCamera(-1, 1, 1, -1, -1, 1);
const light = new THREE.DirectionalLight(0xffffff, 2.5);
// A headlight: from above-left of the eye towards what it looks at (the target moves with the
// camera too, so the light direction is fixed in view space).
light.position.set(-0.3, 0.5, 0);
light.target.position.set(0, 0, -1);
camera.add(light);
camera.add(light.target);
scene.add(camera);

// The frame of the scan (the model when there is no point).
const box = new THREE.Box3();
if (count > 0) box.setFromBufferAttribute(geometry.getAttribute('position'));
else if (model) box.setFromObject(model);
const centre = box.getCenter(new THREE.Vector3());
const radius = Math.max(box.getSize(new THREE.Vector3()).length() / 2, 1e-9);
const target = centre.clone();
// The box's extent across and up the first view (what the PNG frames too).
const eye = new THREE.Vector3(...view.eye), up0 = new THREE.Vector3(...view.up);
const right0 = new THREE.Vector3().crossVectors(up0, eye).normalize();
let extentX = 1e-9, extentY = 1e-9;
for (let c = 0; c < 8; ++c) {
  const corner = new THREE.Vector3(c & 1 ? box.max.x : box.min.x, c & 2 ? box.max.y : box.min.y,
                                   c & 4 ? box.max.z : box.min.z).sub(centre);
  extentX = Math.max(extentX, Math.abs(corner.dot(right0)));
  extentY = Math.max(extentY, Math.abs(corner.dot(up0)));
}

function resetView() {
  target.copy(centre);
  camera.up.copy(up0);
  camera.position.copy(centre).addScaledVector(eye, 4 * radius);
  camera.lookAt(target);
  camera.zoom = 1;
  resize();
}

function resize() {
  const w = container.clientWidth, h = container.clientHeight;
  renderer.setSize(w, h, false);
  const aspect = w / Math.max(h, 1);
  // Room for the legend on the right: frame the part in the left 80 % of the width.
  const halfHeight = 1.08 * Math.max(extentY, extentX / (0.8 * aspect));
  camera.left = -halfHeight * aspect; camera.right = halfHeight * aspect;
  camera.top = halfHeight; camera.bottom = -halfHeight;
  camera.near = 0.01 * radius; camera.far = 10 * radius;
  camera.updateProjectionMatrix();
  requestRender();
}

let pending = false, firstFrame = true;
function requestRender() {
  if (pending) return;
  pending = true;
  requestAnimationFrame(() => {
    pending = false;
    renderer.render(scene, camera);
    if (firstFrame) { firstFrame = false; selfCheck(); }
  });
}

// Point size: about the points' spacing on the screen at the first view.
function defaultPointSize() {
  const pixelsPerUnit = container.clientHeight / (camera.top - camera.bottom);
  // The scan's frame on the screen, about half of it covered by the surface seen from the front.
  const area = 4 * extentX * extentY * pixelsPerUnit ** 2 * 0.5;
  return Math.min(6, Math.max(1.5, Math.sqrt(area / Math.max(count, 1)) * 1.5));
}

// ---- orbit, pan, zoom ----
let drag = null;
canvas.addEventListener('contextmenu', (e) => e.preventDefault());
canvas.addEventListener('pointerdown', (e) => {
  drag = { x: e.clientX, y: e.clientY, pan: e.button === 2 || e.shiftKey };
  canvas.setPointerCapture(e.pointerId);
  $('tooltip').hidden = true;
});
canvas.addEventListener('pointerup', (e) => { drag = null; canvas.releasePointerCapture(e.pointerId); });
canvas.addEventListener('pointermove', (e) => {
  if (!drag) { hover(e); return; }
  const dx = e.clientX - drag.x, dy = e.clientY - drag.y;
  drag.x = e.clientX; drag.y = e.clientY;
  const offset = camera.position.clone().sub(target);
  const right = new THREE.Vector3().crossVectors(camera.up, offset).normalize();
  if (drag.pan) {
    const perPixel = ((camera.top - camera.bottom) / camera.zoom) / container.clientHeight;
    const move = right.multiplyScalar(dx * perPixel).addScaledVector(camera.up, dy * perPixel);
    target.add(move); camera.position.add(move);
  } else {
    const q = new THREE.Quaternion().setFromAxisAngle(camera.up, -dx * 0.006)
        .multiply(new THREE.Quaternion().setFromAxisAngle(right, -dy * 0.006));
    offset.applyQuaternion(q);
    camera.up.applyQuaternion(q);
    camera.position.copy(target).add(offset);
  }
  camera.lookAt(target);
  requestRender();
});
canvas.addEventListener('wheel', (e) => {
  e.preventDefault();
  camera.zoom = Math.min(200, Math.max(0.05, camera.zoom * Math.exp(-e.deltaY * 0.0015)));
  camera.updateProjectionMatrix();
  requestRender();
}, { passive: false });

// ---- hover: the front-most shown point within a few pixels of the cursor ----
let faceFilter = -1;
const faceNames = report.faces.map((f) => f.name);
const matrix = new THREE.Matrix4();
function hover(e) {
  const rect = canvas.getBoundingClientRect();
  const mx = (e.clientX - rect.left) / rect.width * 2 - 1;
  const my = 1 - (e.clientY - rect.top) / rect.height * 2;
  camera.updateMatrixWorld();
  matrix.multiplyMatrices(camera.projectionMatrix, camera.matrixWorldInverse);
  const m = matrix.elements;
  const rx = 8 / rect.width * 2, ry = 8 / rect.height * 2;
  let best = -1, bestDepth = Infinity;
  for (let i = 0; i < count; ++i) {
    if (faceFilter >= 0 && faces[i] !== faceFilter) continue;
    const x = positions[3 * i], y = positions[3 * i + 1], z = positions[3 * i + 2];
    const sx = m[0] * x + m[4] * y + m[8] * z + m[12];
    if (Math.abs(sx - mx) > rx) continue;
    const sy = m[1] * x + m[5] * y + m[9] * z + m[13];
    if (Math.abs(sy - my) > ry) continue;
    const sz = m[2] * x + m[6] * y + m[10] * z + m[14];
    if (sz < bestDepth) { bestDepth = sz; best = i; }
  }
  const tip = $('tooltip');
  if (best < 0) { tip.hidden = true; return; }
  const d = deviation[best];
  const [lo, hi] = view.band;
  const where = d < lo ? 'below tolerance' : d > hi ? 'above tolerance' : 'inside tolerance';
  tip.innerHTML = `<b>${fmt(d)} ${view.units}</b> <span class="${d < lo || d > hi ? 'bad' : 'ok'}">${where}</span><br>` +
      `face ${faces[best]} ${faceNames[faces[best]] ? '“' + faceNames[faces[best]].replace(/</g, '&lt;') + '”' : ''}<br>` +
      `<span class="xyz">x ${positions[3 * best].toFixed(3)}  y ${positions[3 * best + 1].toFixed(3)}  z ${positions[3 * best + 2].toFixed(3)}</span>`;
  tip.style.left = (e.clientX - rect.left + 14) + 'px';
  tip.style.top = (e.clientY - rect.top + 14) + 'px';
  tip.hidden = false;
}
canvas.addEventListener('pointerleave', () => { $('tooltip').hidden = true; });

// ---- one face alone (a table row's click) ----
function showFace(face) {
  faceFilter = face;
  for (let i = 0; i < count; ++i) {
    const keep = face < 0 || faces[i] === face;
    for (let c = 0; c < 3; ++c) shown[3 * i + c] = keep ? colours[3 * i + c] : 222;
  }
  colourAttribute.needsUpdate = true;
  $('clear-face').hidden = face < 0;
  table.querySelectorAll('tbody tr').forEach((row) => row.classList.toggle('selected', Number(row.dataset.face) === face));
  requestRender();
}
table.tBodies[0].addEventListener('click', (e) => {
  const row = e.target.closest('tr');
  if (row) showFace(Number(row.dataset.face) === faceFilter ? -1 : Number(row.dataset.face));
});
$('clear-face').addEventListener('click', () => showFace(-1));
$('show-model').addEventListener('change', (e) => { if (model) model.visible = e.target.checked; requestRender(); });
if (!model) { $('show-model').disabled = true; $('show-model').checked = false; }
$('point-size').addEventListener('input', (e) => { material.size = Number(e.target.value) * (window.devicePixelRatio || 1); requestRender(); });
$('reset-view').addEventListener('click', resetView);
window.addEventListener('resize', resize);

// ---- the self-check: was anything drawn, and in the map's colours? ----
function selfCheck() {
  const gl = renderer.getContext();
  const w = gl.drawingBufferWidth, h = gl.drawingBufferHeight;
  const pixels = new Uint8Array(w * h * 4);
  gl.readPixels(0, 0, w, h, gl.RGBA, gl.UNSIGNED_BYTE, pixels);
  const bg = [background.r * 255, background.g * 255, background.b * 255].map(Math.round);
  let drawn = 0, coloured = 0;
  for (let k = 0; k < pixels.length; k += 4) {
    const r = pixels[k], g = pixels[k + 1], b = pixels[k + 2];
    if (Math.abs(r - bg[0]) + Math.abs(g - bg[1]) + Math.abs(b - bg[2]) > 6) ++drawn;
    if (Math.max(r, g, b) - Math.min(r, g, b) > 40) ++coloured;  // not grey: the colour map
  }
  // Hover over a shown point (the middle one of the subset, where it lies on the screen): the
  // tooltip must name a point's deviation.
  if (count > 0) {
    const k = Math.floor(count / 2);
    const p = new THREE.Vector3(positions[3 * k], positions[3 * k + 1], positions[3 * k + 2]).project(camera);
    const rect = canvas.getBoundingClientRect();
    hover({ clientX: rect.left + (p.x + 1) / 2 * rect.width, clientY: rect.top + (1 - p.y) / 2 * rect.height });
    const tip = $('tooltip');
    check.dataset.hover = !tip.hidden && /[+-]\d+\.\d{4} /.test(tip.textContent) ? 'ok' : 'failed';
    tip.hidden = true;
  }
  check.dataset.drawnPixels = drawn;
  check.dataset.colouredPixels = coloured;
  check.dataset.points = count;
  check.dataset.readyMs = Math.round(performance.now() - started);
  check.dataset.errors = window.__errors.join(' | ');
  check.dataset.status =
      window.__errors.length === 0 && coloured > 0 && check.dataset.hover !== 'failed' ? 'ok' : 'failed';
}

$('view-note').textContent = `first view: ${view.view}`;
resetView();
const size = defaultPointSize();
$('point-size').value = size.toFixed(1);
material.size = size * (window.devicePixelRatio || 1);
requestRender();
