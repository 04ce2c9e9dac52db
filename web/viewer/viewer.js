// The page of `mgcloth view DIR` and `mgcloth render DIR`. The server gives DIR under /data/ and its file list at
// /api/listing.json. A run folder (frame_NNNNN.obj or animation.glb) is played in 3D with its stats.csv plotted
// beside it; a `mgcloth bench convergence` folder shows its convergence plot. Query parameters: frame=N (the frame
// shown first), mode=shaded|wire, source=glb|obj, fps=F, play=1, render=1 (the picture only, for screenshots).
// Nothing is loaded from outside this server.
import * as THREE from 'three';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';
import { GlbFrames, ObjFrames } from './frames.js';
import { buildObstacles, MeshObstacles } from './obstacles.js';
import { LinePlot, parseCsv, PALETTE } from './plots.js';

const params = new URLSearchParams(location.search);
const DATA = params.get('data') || '/data/';
const RENDER = params.get('render') === '1';
if (RENDER) document.body.classList.add('render');
const $ = (id) => document.getElementById(id);

/** What the end-to-end test and `mgcloth render` look at. */
const api = {
  ready: false,
  error: null,
  state: { kind: null, source: null, frameIndex: -1, frameNumber: -1, frameCount: 0, time: 0, playing: false, shown: 0,
           mode: 'shaded', vertices: 0, triangles: 0 },
  play() {}, pause() {}, seek() {}, setMode() {},
  /** The obstacles drawn: name, whether shown, vertices, triangles and world bounding box (min, max). */
  obstacles() { return []; },
  /** Shows or hides every obstacle (to tell what they add to a picture). */
  showObstacles() {},
  /** Luminance statistics of a canvas (the 3D view by default), to tell a drawing from a blank one. */
  canvasStats(selector = '#view canvas') {
    const c = document.querySelector(selector);
    if (!c) return null;
    let data, w = c.width, h = c.height;
    if (c === api._renderer?.domElement) {
      api._draw();  // read in the same task as the draw: the drawing buffer is not preserved
      const gl = api._renderer.getContext();
      data = new Uint8Array(4 * w * h);
      gl.readPixels(0, 0, w, h, gl.RGBA, gl.UNSIGNED_BYTE, data);
    } else {
      data = c.getContext('2d').getImageData(0, 0, w, h).data;
    }
    let n = 0, sum = 0, sum2 = 0, warm = 0, cool = 0;
    const colors = new Set();
    for (let i = 0; i < data.length; i += 4 * 7) {
      const l = 0.299 * data[i] + 0.587 * data[i + 1] + 0.114 * data[i + 2];
      sum += l; sum2 += l * l; ++n;
      if (data[i] > data[i + 2] + 40) ++warm;
      else if (data[i + 2] > data[i] + 40) ++cool;
      if (colors.size < 4096) colors.add((data[i] << 16) | (data[i + 1] << 8) | data[i + 2]);
    }
    const mean = sum / n;
    // warm, cool: fractions of pixels clearly redder or bluer than they are the other, to tell tints apart.
    return { width: w, height: h, mean, std: Math.sqrt(Math.max(0, sum2 / n - mean * mean)), colors: colors.size,
             warm: warm / n, cool: cool / n };
  },
};
window.mgclothViewer = api;

function setStatus(text, error = false) {
  $('status').textContent = text;
  $('status').classList.toggle('error', error);
}

function fail(e) {
  const message = e?.message || String(e);
  console.error(e);
  api.error = message;
  document.body.dataset.error = message;
  setStatus(message, true);
}

function markReady(caption) {
  api.ready = true;
  document.body.dataset.caption = caption;
  document.body.dataset.ready = '1';
}

async function fetchOk(url) {
  const r = await fetch(url);
  if (!r.ok) throw new Error(`${url}: HTTP ${r.status}`);
  return r;
}

// ---------------------------------------------------------------------------------------------------------------
// A run: the cloth and obstacles in 3D, stats beside.

/** A tileable grid for the cloth, so that stretch and shear show; one tile is 10 cm of material. */
function clothTexture() {
  const size = 128, c = document.createElement('canvas');
  c.width = c.height = size;
  const g = c.getContext('2d');
  g.fillStyle = '#e9edf3';
  g.fillRect(0, 0, size, size);
  g.fillStyle = '#d3dae6';
  g.fillRect(0, 0, size / 2, size / 2);
  g.fillRect(size / 2, size / 2, size / 2, size / 2);
  g.strokeStyle = '#8e9bb3';
  g.lineWidth = 3;
  g.strokeRect(0, 0, size, size);
  const t = new THREE.CanvasTexture(c);
  t.wrapS = t.wrapT = THREE.RepeatWrapping;
  t.repeat.set(10, 10);
  t.colorSpace = THREE.SRGBColorSpace;
  return t;
}

function statsPlots(stats, onPick) {
  const side = $('side');
  const cols = new Set(stats.columns);
  const charts = [
    { column: 'iterations', title: 'solver iterations per step' },
    { column: 'energy', title: 'energy at the end of the step' },
    { column: 'wall_ms', title: 'wall time per step (ms)' },
  ].filter((c) => cols.has(c.column));
  const byCloth = new Map();
  for (const r of stats.rows) {
    const key = r.cloth ?? '';
    if (!byCloth.has(key)) byCloth.set(key, []);
    byCloth.get(key).push(r);
  }
  const plots = charts.map((chart) => {
    const canvas = document.createElement('canvas');
    canvas.dataset.column = chart.column;
    side.appendChild(canvas);
    const plot = new LinePlot(canvas, { title: chart.title, xLabel: 'simulated time (s)', onPick });
    plot.setSeries([...byCloth].map(([name, rows], k) => ({
      name: name || 'cloth', color: PALETTE[k % PALETTE.length],
      x: rows.map((r) => +r.sim_time), y: rows.map((r) => +r[chart.column]),
    })));
    return plot;
  });
  new ResizeObserver(() => plots.forEach((p) => p.draw())).observe(side);
  return plots;
}

async function startRun(listing, names) {
  const frameFiles = [...names].filter((n) => /^frame_\d{5}\.obj$/.test(n)).sort();
  const hasGlb = names.has('animation.glb');
  const scene = names.has('scene.resolved.json') ? await (await fetchOk(DATA + 'scene.resolved.json')).json() : null;
  const timeStep = scene?.time_step ?? 1 / 30;
  const source = params.get('source') || (hasGlb ? 'glb' : 'obj');
  if (source === 'glb' && !hasGlb) throw new Error('source=glb: the folder has no animation.glb');
  if (source === 'obj' && !frameFiles.length) throw new Error('source=obj: the folder has no frame_NNNNN.obj');
  setStatus(`loading ${source === 'glb' ? 'animation.glb' : `${frameFiles.length} OBJ frames`}…`);
  const frames = source === 'glb' ? await GlbFrames.open(DATA + 'animation.glb', timeStep)
                                  : await ObjFrames.open(DATA, frameFiles, timeStep);
  const n = frames.frames.length;
  Object.assign(api.state, { kind: 'run', source, frameCount: n, vertices: frames.numVertices,
                             triangles: frames.index.length / 3 });

  // Which frame first: ?frame=N names a simulation frame; a picture defaults to the last, the viewer to the first.
  let start = RENDER ? n - 1 : 0;
  if (params.has('frame')) {
    const want = parseInt(params.get('frame'), 10);
    start = frames.frames.findIndex((f) => f.number === want);
    if (start < 0) {
      throw new Error(`frame ${params.get('frame')} is not in the ${source === 'glb' ? 'animation.glb' : 'OBJ frames'} ` +
                      `(frames ${frames.frames[0].number}-${frames.frames[n - 1].number}, ${n} recorded)`);
    }
  }

  // Three.js scene in simulation coordinates: z up, metres.
  const view = $('view');
  const renderer = new THREE.WebGLRenderer({ antialias: true });
  renderer.setPixelRatio(window.devicePixelRatio || 1);
  renderer.shadowMap.enabled = true;
  renderer.shadowMap.type = THREE.PCFSoftShadowMap;
  view.appendChild(renderer.domElement);
  const world = new THREE.Scene();
  world.background = new THREE.Color(0xf3f4f6);
  const camera = new THREE.PerspectiveCamera(35, 1, 0.01, 1000);
  camera.up.set(0, 0, 1);
  const controls = new OrbitControls(camera, renderer.domElement);
  controls.enableDamping = !RENDER;

  world.add(new THREE.HemisphereLight(0xffffff, 0x6b7280, 1.0));
  const sun = new THREE.DirectionalLight(0xffffff, 2.6);
  sun.castShadow = true;
  sun.shadow.mapSize.set(2048, 2048);
  world.add(sun, sun.target);

  const geometry = new THREE.BufferGeometry();
  geometry.setAttribute('position', new THREE.BufferAttribute(new Float32Array(3 * frames.numVertices), 3));
  if (frames.uv) geometry.setAttribute('uv', new THREE.BufferAttribute(frames.uv, 2));
  geometry.setIndex(new THREE.BufferAttribute(frames.index, 1));
  // One colour per body when the run says which triangles are whose (surfaces.json), so layers tell apart.
  const surfaces = names.has('surfaces.json') ? await (await fetchOk(DATA + 'surfaces.json')).json() : null;
  const tint = (hex) => new THREE.Color(hex).lerp(new THREE.Color(0xffffff), frames.uv ? 0.35 : 0.0);
  const texture = frames.uv ? clothTexture() : null;
  const clothMaterial = (color) => new THREE.MeshStandardMaterial({ color, roughness: 0.85, side: THREE.DoubleSide,
                                                                    map: texture });
  let shaded = clothMaterial(texture ? 0x8fb5ec : 0x6f9fe0);
  if (surfaces && surfaces.length > 1) {
    const tris = frames.index.length / 3;
    const ok = Array.isArray(surfaces) && surfaces.every((b, k) => Array.isArray(b.triangles) && b.triangles.length === 2 &&
                                                           b.triangles[0] === (k ? surfaces[k - 1].triangles[0] + surfaces[k - 1].triangles[1] : 0)) &&
               surfaces.at(-1).triangles[0] + surfaces.at(-1).triangles[1] === tris;
    if (!ok) throw new Error(`surfaces.json: its triangle ranges do not cover the ${tris} triangles of the frames`);
    shaded = surfaces.map((b, k) => {
      geometry.addGroup(3 * b.triangles[0], 3 * b.triangles[1], k);
      return clothMaterial(tint(PALETTE[k % PALETTE.length]));
    });
  }
  api.state.surfaces = surfaces ? surfaces.map((b) => b.name) : [];
  const wire = new THREE.MeshBasicMaterial({ color: 0x1d3b6e, wireframe: true });
  const cloth = new THREE.Mesh(geometry, shaded);
  cloth.castShadow = cloth.receiveShadow = true;
  world.add(cloth);

  const solid = new THREE.MeshStandardMaterial({ color: 0xb9b3aa, roughness: 0.6, metalness: 0.0 });
  // Mesh obstacles may be open (a funnel) or inconsistently oriented: drawn from both sides.
  const bothSides = solid.clone();
  bothSides.side = THREE.DoubleSide;
  const floorMaterial = new THREE.MeshStandardMaterial({ color: 0xdedbd5, roughness: 0.95, side: THREE.DoubleSide });
  let obstacleMeshes = [], poseObstacles = () => {}, meshObstacles = null;
  const first = await frames.positions(0);
  const box0 = new THREE.Box3().setFromArray(first);
  if (frames.kind === 'glb') {
    world.add(frames.root);
    obstacleMeshes = frames.obstacles;
    for (const m of obstacleMeshes) {
      m.geometry.computeVertexNormals();
      // mgcloth writes a plane as one square (4 vertices) sized to lie under the whole animation.
      m.userData.plane = m.geometry.attributes.position.count === 4;
      m.material = m.userData.plane ? floorMaterial : bothSides;
    }
    poseObstacles = (k) => frames.setFrame(k);
  } else {
    // Shapes from the scene; triangle meshes (a walking body, sequences, skins) from the frames the run wrote of
    // them, which may be open or inconsistently oriented surfaces: drawn from both sides.
    const built = scene?.obstacles?.length ? buildObstacles(scene.obstacles, box0, solid) : null;
    for (const m of built?.meshes || []) {
      if (m.userData.plane) m.material = floorMaterial;
      world.add(m);
      obstacleMeshes.push(m);
    }
    if (names.has('obstacles.json')) {
      meshObstacles = await MeshObstacles.open(DATA, names, bothSides);
      for (const m of meshObstacles.meshes) {
        world.add(m);
        obstacleMeshes.push(m);
      }
    }
    poseObstacles = async (k) => {
      built?.setTime(frames.frames[k].time);
      if (meshObstacles) await meshObstacles.setFrame(frames.frames[k].number);
    };
  }
  for (const m of obstacleMeshes) m.castShadow = m.receiveShadow = true;
  api.state.obstacles = obstacleMeshes.map((m) => m.name);
  api.obstacles = () => obstacleMeshes.map((m) => {
    m.updateMatrixWorld(true);
    const b = new THREE.Box3().setFromObject(m);
    return { name: m.name, visible: m.visible, vertices: m.geometry.attributes.position.count,
             triangles: (m.geometry.index ? m.geometry.index.count : m.geometry.attributes.position.count) / 3,
             min: b.min.toArray(), max: b.max.toArray() };
  });
  let obstaclesHidden = false;

  // Camera: fit the cloth (its first and shown frames in the viewer, the shown one in a picture) and the bounded
  // obstacles, seen from the front, above.
  const frameView = async () => {
    const shownBox = new THREE.Box3().setFromArray(await frames.positions(start));
    const box = RENDER ? shownBox : box0.clone().union(shownBox);
    await poseObstacles(start);
    world.updateMatrixWorld(true);
    for (const m of obstacleMeshes) if (!m.userData.plane && m.visible) box.union(new THREE.Box3().setFromObject(m));
    const center = box.getCenter(new THREE.Vector3());
    const radius = Math.max(box.getSize(new THREE.Vector3()).length() / 2, 1e-3);
    const dir = new THREE.Vector3(0.55, -1.0, 0.62).normalize();
    const fov = THREE.MathUtils.degToRad(camera.fov);
    const corners = [];
    for (let i = 0; i < 8; ++i) {
      corners.push(new THREE.Vector3(i & 1 ? box.max.x : box.min.x, i & 2 ? box.max.y : box.min.y,
                                     i & 4 ? box.max.z : box.min.z).sub(center));
    }
    const fit = () => {
      // The nearest distance along `dir` at which every corner of the box is inside the view, plus a margin.
      const right = new THREE.Vector3().crossVectors(camera.up, dir).normalize();
      const up = new THREE.Vector3().crossVectors(dir, right);
      const tv = Math.tan(fov / 2), th = tv * camera.aspect;
      let distance = 0;
      for (const p of corners) {
        const z = p.dot(dir);
        distance = Math.max(distance, z + Math.abs(p.dot(right)) / th, z + Math.abs(p.dot(up)) / tv);
      }
      camera.position.copy(center).addScaledVector(dir, distance * 1.08);
      camera.near = radius / 50;
      camera.far = radius * 200;
      camera.updateProjectionMatrix();
      controls.target.copy(center);
      controls.update();
    };
    // The light follows the scene's size, so the shadow map covers it whatever its scale.
    sun.position.copy(center).add(new THREE.Vector3(-1.2 * radius, -1.6 * radius, 2.6 * radius));
    sun.target.position.copy(center);
    const sc = sun.shadow.camera;
    sc.left = sc.bottom = -2 * radius;
    sc.right = sc.top = 2 * radius;
    sc.near = 0.1 * radius;
    sc.far = 8 * radius;
    sc.updateProjectionMatrix();
    // Offsets against shadow acne on the cloth's own folds, scaled to the scene like the map.
    sun.shadow.bias = -0.0005;
    sun.shadow.normalBias = 0.015 * radius;
    return fit;
  };
  const fit = await frameView();

  let dirty = true;
  const invalidate = () => { dirty = true; };
  controls.addEventListener('change', invalidate);
  const resize = () => {
    invalidate();
    const w = Math.max(1, view.clientWidth), h = Math.max(1, view.clientHeight);
    renderer.setSize(w, h, false);
    camera.aspect = w / h;
    camera.updateProjectionMatrix();
  };
  resize();
  fit();
  new ResizeObserver(resize).observe(view);
  api._renderer = renderer;
  api._draw = () => renderer.render(world, camera);

  // Stats beside the animation.
  const nearestFrame = (t) => {
    let best = 0;
    frames.frames.forEach((f, k) => { if (Math.abs(f.time - t) < Math.abs(frames.frames[best].time - t)) best = k; });
    return best;
  };
  let plots = [];
  if (!RENDER && names.has('stats.csv')) {
    const stats = parseCsv(await (await fetchOk(DATA + 'stats.csv')).text());
    if (stats.rows.length) plots = statsPlots(stats, (t) => { pause(); show(nearestFrame(t)); });
  }

  // Controls.
  const scrub = $('scrub'), label = $('frame-label'), playButton = $('play'), fpsInput = $('fps');
  scrub.max = String(n - 1);
  const spacing = n > 1 ? (frames.frames[n - 1].time - frames.frames[0].time) / (n - 1) : timeStep;
  fpsInput.value = params.get('fps') || String(Math.min(60, Math.max(1, Math.round(1 / spacing))));
  const last = frames.frames[n - 1].number;
  let current = -1, pending = null, showing = Promise.resolve();

  const setMode = (mode) => {
    api.state.mode = mode === 'wire' ? 'wire' : 'shaded';
    cloth.material = api.state.mode === 'wire' ? wire : shaded;
    cloth.castShadow = api.state.mode !== 'wire';
    $('mode').value = api.state.mode;
    invalidate();
  };
  setMode(params.get('mode') || 'shaded');
  $('mode').addEventListener('change', (e) => setMode(e.target.value));

  // Frames are shown in order; a request while one loads replaces any other waiting request.
  function show(k) {
    pending = k;
    showing = showing.then(async () => {
      if (pending === null) return;
      const want = pending;
      pending = null;
      const [p] = await Promise.all([frames.positions(want), meshObstacles?.positions(frames.frames[want].number)]);
      geometry.attributes.position.array.set(p);
      geometry.attributes.position.needsUpdate = true;
      geometry.computeVertexNormals();
      geometry.computeBoundingSphere();
      await poseObstacles(want);
      if (obstaclesHidden) for (const m of obstacleMeshes) m.visible = false;
      invalidate();
      current = want;
      const f = frames.frames[want];
      scrub.value = String(want);
      label.textContent = `frame ${f.number} / ${last}   t = ${f.time.toFixed(3)} s`;
      plots.forEach((pl) => pl.setMarker(f.time));
      Object.assign(api.state, { frameIndex: want, frameNumber: f.number, time: f.time, shown: api.state.shown + 1 });
      for (let j = 1; j <= 3; ++j) {  // read ahead
        if (want + j >= n) break;
        frames.positions(want + j).catch(() => {});
        meshObstacles?.positions(frames.frames[want + j].number).catch(() => {});
      }
    }).catch(fail);
    return showing;
  }

  let playing = false, lastStep = 0;
  function play() {
    if (n < 2) return;
    playing = true;
    api.state.playing = true;
    playButton.textContent = '❚❚';
  }
  function pause() {
    playing = false;
    api.state.playing = false;
    playButton.textContent = '▶';
  }
  playButton.addEventListener('click', () => (playing ? pause() : play()));
  scrub.addEventListener('input', () => { pause(); show(parseInt(scrub.value, 10)); });
  window.addEventListener('keydown', (e) => {
    if (e.target.tagName === 'INPUT' && e.target.type === 'number') return;
    if (e.key === ' ') { e.preventDefault(); playing ? pause() : play(); }
    else if (e.key === 'ArrowRight') { pause(); show(Math.min(n - 1, current + 1)); }
    else if (e.key === 'ArrowLeft') { pause(); show(Math.max(0, current - 1)); }
  });
  Object.assign(api, { play, pause, seek: (k) => { pause(); return show(k); }, setMode });
  api.showObstacles = (on) => {
    obstaclesHidden = !on;
    for (const m of obstacleMeshes) m.visible = !!on;
    return show(current);  // poses them again, which shows each mesh that has positions at this frame
  };

  if (frames.kind === 'glb' && frameFiles.length) {
    $('source-label').hidden = false;
    $('source').value = source;
    $('source').addEventListener('change', (e) => {
      params.set('source', e.target.value);
      location.search = params.toString();
    });
  }
  $('controls').hidden = false;
  $('title').textContent = listing.dir;
  setStatus(`${frames.kind === 'glb' ? 'animation.glb' : 'OBJ frames'}: ${n} frames, ` +
            `${frames.numVertices.toLocaleString('en')} vertices, ${obstacleMeshes.length} ` +
            `obstacle${obstacleMeshes.length === 1 ? '' : 's'}`);

  renderer.setAnimationLoop((now) => {
    const fps = Math.max(1, Math.min(120, parseFloat(fpsInput.value) || 30));
    if (playing && pending === null && now - lastStep >= 1000 / fps) {
      const next = (current + 1) % n;
      const number = frames.frames[next].number;
      if ((frames.isLoaded(next) || frames.kind === 'glb') && (!meshObstacles || meshObstacles.isLoaded(number))) {
        lastStep = now;
        show(next);
      } else {
        frames.positions(next).catch(fail);
        meshObstacles?.positions(number).catch(fail);
      }
    }
    // Drawn only when something changed: SwiftShader (headless Chromium) draws on the CPU, and a laptop's GPU
    // need not spin while the animation is paused.
    if (controls.update() || dirty) {
      dirty = false;
      renderer.render(world, camera);
    }
  });

  await show(start);
  await new Promise((r) => requestAnimationFrame(() => requestAnimationFrame(r)));  // drawn at least once
  const f = frames.frames[start];
  markReady(`${listing.dir}: frame ${f.number} of ${last} (t = ${f.time.toFixed(3)} s, ${source}, ` +
            `${frames.numVertices} vertices)`);
  if (params.get('play') === '1') play();
}

// ---------------------------------------------------------------------------------------------------------------
// A bench folder: the convergence traces of `mgcloth bench convergence` (Wang et al. 2018, Fig. 4).

async function startConvergence(listing, names) {
  document.body.classList.add('plots');
  const csv = parseCsv(await (await fetchOk(DATA + 'convergence.csv')).text());
  for (const c of ['solver', 'wall_s', 'rel_energy_error', 'grad_norm'])
    if (!csv.columns.includes(c)) throw new Error(`convergence.csv: no column "${c}" (got ${csv.columns.join(',')})`);
  if (!csv.rows.length) throw new Error('convergence.csv: no rows');
  let title = listing.dir;
  if (names.has('convergence.json')) {
    const j = await (await fetchOk(DATA + 'convergence.json')).json();
    if (j.scene) title = `${j.scene.split('/').pop()}, ${Number(j.vertices).toLocaleString('en')} vertices, step ${j.step}`;
  }
  const bySolver = new Map();
  for (const r of csv.rows) {
    if (!bySolver.has(r.solver)) bySolver.set(r.solver, []);
    bySolver.get(r.solver).push(r);
  }
  const FLOOR = 1e-16;
  const series = (column, floor) => [...bySolver].map(([name, rows], k) => {
    const kept = rows.filter((r) => !Number.isNaN(+r[column]));
    return { name, color: PALETTE[k % PALETTE.length], x: kept.map((r) => +r.wall_s),
             y: kept.map((r) => (floor ? Math.max(+r[column], floor) : +r[column])) };
  });
  const side = $('side');
  const errorCanvas = document.createElement('canvas');
  errorCanvas.dataset.column = 'rel_energy_error';
  side.appendChild(errorCanvas);
  const plots = [new LinePlot(errorCanvas, { title, logY: true, floor: FLOOR, hLines: [1e-2, 1e-3, 1e-4], markers: true,
                                             xMin: 0, xLabel: 'wall time (s)',
                                             yLabel: 'relative energy error (E − E*) / (E₀ − E*)' })];
  plots[0].setSeries(series('rel_energy_error', FLOOR));
  if (!RENDER) {
    const gradCanvas = document.createElement('canvas');
    gradCanvas.dataset.column = 'grad_norm';
    side.appendChild(gradCanvas);
    plots.push(new LinePlot(gradCanvas, { title: 'gradient norm ‖∇E‖', logY: true, markers: true, xMin: 0,
                                          xLabel: 'wall time (s)', yLabel: '‖∇E‖' }));
    plots[1].setSeries(series('grad_norm', 0));
  }
  new ResizeObserver(() => plots.forEach((p) => p.draw())).observe(side);
  api.state.kind = 'convergence';
  $('title').textContent = listing.dir;
  setStatus(`convergence.csv: ${bySolver.size} solvers, ${csv.rows.length} iterations`);
  await new Promise((r) => requestAnimationFrame(r));
  plots.forEach((p) => p.draw());
  markReady(`${listing.dir}: convergence of ${[...bySolver.keys()].join(', ')}`);
}

/** Any other folder with pictures (e.g. bench scalability): shows them. */
async function startGallery(listing, pngs) {
  document.body.classList.add('plots');
  const side = $('side');
  side.classList.add('gallery');
  await Promise.all(pngs.map((name) => new Promise((resolve, reject) => {
    const img = new Image();
    img.onload = resolve;
    img.onerror = () => reject(new Error(`${name}: cannot load`));
    img.src = DATA + encodeURIComponent(name);
    img.alt = name;
    side.appendChild(img);
  })));
  api.state.kind = 'gallery';
  $('title').textContent = listing.dir;
  setStatus(`${pngs.length} pictures`);
  markReady(`${listing.dir}: ${pngs.join(', ')}`);
}

async function main() {
  const listing = await (await fetchOk('/api/listing.json')).json();
  const names = new Set(listing.files.map((f) => f.name));
  document.title = `mgcloth: ${listing.dir}`;
  const pngs = [...names].filter((n) => n.endsWith('.png')).sort();
  if ([...names].some((n) => /^frame_\d{5}\.obj$/.test(n)) || names.has('animation.glb')) return startRun(listing, names);
  if (names.has('convergence.csv')) return startConvergence(listing, names);
  if (pngs.length) return startGallery(listing, pngs);
  throw new Error(`${listing.dir}: nothing to show (no frame_NNNNN.obj, animation.glb, convergence.csv or .png)`);
}

main().catch(fail);
