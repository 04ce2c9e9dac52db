#!/usr/bin/env node
// End-to-end test of `mgcloth view` and `mgcloth render` in headless Chromium (registered in CTest as viewer_e2e):
// a tiny run made here is played (animation.glb and OBJ frames), scrubbed and drawn both ways; its stats and a
// bench folder's convergence plot must be drawn; `render` must write a picture that is not blank; the page must
// ask for nothing outside 127.0.0.1.
//   node web/tests/viewer_e2e.mjs --cli build/bin/mgcloth --work DIR
// Exit 77 (CTest's SKIP_RETURN_CODE) when Chromium or web/node_modules is missing: scripts/setup.sh installs both.
import { spawn, spawnSync } from 'node:child_process';
import fs from 'node:fs';
import path from 'node:path';
import { fileURLToPath } from 'node:url';

const here = path.dirname(fileURLToPath(import.meta.url));
const SKIP = 77;

function option(name, fallback) {
  const i = process.argv.indexOf(`--${name}`);
  return i > 0 ? process.argv[i + 1] : fallback;
}
const cli = path.resolve(option('cli', path.join(here, '../../build/bin/mgcloth')));
const work = path.resolve(option('work', fs.mkdtempSync('/tmp/mgcloth_viewer_e2e_')));

const { findChromium, launch, localOnly } = await import('../chromium.mjs');
try {
  await import('playwright-core');
} catch {
  console.log('SKIP: playwright-core is not installed in web/node_modules (run scripts/setup.sh, or npm ci in web/)');
  process.exit(SKIP);
}
const chromiumPath = findChromium();
if (!chromiumPath) {
  console.log("SKIP: Chromium not found (scripts/setup.sh installs Debian's chromium; or set MGCLOTH_CHROMIUM)");
  process.exit(SKIP);
}

let failures = 0;
function check(ok, what) {
  console.log(`${ok ? 'ok  ' : 'FAIL'} ${what}`);
  if (!ok) ++failures;
}

function run(args, { allowFail = false } = {}) {
  const r = spawnSync(cli, args, { encoding: 'utf8', timeout: 60000 });
  if (!allowFail && r.status !== 0) throw new Error(`mgcloth ${args.join(' ')} failed (${r.status}): ${r.stderr}`);
  return r;
}

/** Starts `mgcloth view DIR --port 0` and resolves with its URL once printed. */
function view(dir) {
  const child = spawn(cli, ['view', dir, '--port', '0'], { stdio: ['ignore', 'pipe', 'pipe'] });
  return new Promise((resolve, reject) => {
    let out = '';
    const timer = setTimeout(() => reject(new Error(`mgcloth view ${dir}: no URL after 10 s: ${out}`)), 10000);
    child.stdout.on('data', (d) => {
      out += d;
      const m = /(http:\/\/127\.0\.0\.1:\d+\/)/.exec(out);
      if (m) { clearTimeout(timer); resolve({ url: m[1], child }); }
    });
    child.stderr.on('data', (d) => { out += d; });
    child.on('exit', (code) => { clearTimeout(timer); reject(new Error(`mgcloth view ${dir} exited (${code}): ${out}`)); });
  });
}

function stop(child) {
  return new Promise((resolve) => {
    child.removeAllListeners('exit');
    child.on('exit', (code) => resolve(code));
    child.kill('SIGINT');
  });
}

// A cloth of 100 vertices falling onto a ball over a floor: made in well under a second.
fs.rmSync(work, { recursive: true, force: true });
fs.mkdirSync(work, { recursive: true });
const scene = {
  frames: 6,
  cloths: [{ name: 'cloth', mesh: { width: 0.6, height: 0.6, vertices: 100 }, transform: { translation: [-0.3, -0.3, 0.2] } }],
  obstacles: [{ name: 'ball', shape: { type: 'sphere', radius: 0.15 }, friction: 0.3 },
              { name: 'floor', shape: { type: 'plane' }, position: [0, 0, -0.2] }],
  solver: { name: 'newton-direct', rel_grad: 1e-3, max_iters: 50 },
  output: { format: ['obj', 'glb'] },
};
const runDir = path.join(work, 'run');
fs.writeFileSync(path.join(work, 'tiny.json'), JSON.stringify(scene));
let glb = true;
if (run(['run', path.join(work, 'tiny.json'), '--out', runDir, '-q'], { allowFail: true }).status !== 0) {
  glb = false;  // a build without tinygltf: OBJ frames only
  scene.output.format = ['obj'];
  fs.writeFileSync(path.join(work, 'tiny.json'), JSON.stringify(scene));
  run(['run', path.join(work, 'tiny.json'), '--out', runDir, '-q']);
}
// Two cloths side by side (OBJ frames): each gets its own colour.
const layersDir = path.join(work, 'layers');
const two = {
  frames: 2,
  cloths: [{ name: 'left', mesh: { width: 0.3, height: 0.6, vertices: 60 }, transform: { translation: [-0.35, -0.3, 0] } },
           { name: 'right', mesh: { width: 0.3, height: 0.6, vertices: 60 }, transform: { translation: [0.05, -0.3, 0] } }],
  solver: { name: 'newton-direct', rel_grad: 1e-3, max_iters: 50 },
  output: { format: ['obj'] },
};
fs.writeFileSync(path.join(work, 'two.json'), JSON.stringify(two));
run(['run', path.join(work, 'two.json'), '--out', layersDir, '-q']);

// The walking body (a mesh obstacle) beside a small cloth, OBJ frames only: the body comes from the frames of it that
// the run wrote (obstacles.json, obstacles_NNNNN.bin).
const bodyDir = path.join(work, 'body');
const walker = {
  frames: 3, time_step: 0.1, cloth_contact: {},
  cloths: [{ name: 'cloth', mesh: { width: 0.3, height: 0.3, vertices: 36 }, transform: { translation: [0.3, 0.2, 0.9] } }],
  obstacles: [{ name: 'body', body: { resolution: 0.05, walk: { stand: 0.05, ramp: 0.1 } } }],
  solver: { name: 'newton-direct', rel_grad: 1e-3, max_iters: 50 },
  output: { format: ['obj'] },
};
fs.writeFileSync(path.join(work, 'walker.json'), JSON.stringify(walker));
run(['run', path.join(work, 'walker.json'), '--out', bodyDir, '-q']);

// A bench folder as `mgcloth bench convergence` writes it (two solvers, made-up traces).
const benchDir = path.join(work, 'bench');
fs.mkdirSync(benchDir);
let csv = 'solver,iteration,wall_s,energy,grad_norm,rel_energy_error\n';
for (const [solver, rate] of [['fmg', 0.2], ['newton-direct', 0.6]])
  for (let k = 0; k <= 12; ++k) csv += `${solver},${k},${(0.05 * k).toFixed(3)},${1 + rate ** k},${10 * rate ** k},${rate ** k}\n`;
fs.writeFileSync(path.join(benchDir, 'convergence.csv'), csv);

const browser = await launch(chromiumPath);
const servers = [];
try {
  const page = await browser.newPage({ viewport: { width: 1100, height: 600 } });
  const refused = await localOnly(page);
  const errors = [];
  page.on('pageerror', (e) => errors.push(String(e)));
  page.on('console', (m) => { if (m.type() === 'error') errors.push(m.text()); });
  const ready = () => page.waitForFunction(() => document.body.dataset.ready === '1' || document.body.dataset.error,
                                           null, { timeout: 30000 });
  const state = () => page.evaluate(() => ({ ...window.mgclothViewer.state, error: window.mgclothViewer.error }));
  const stats = (sel) => page.evaluate((s) => window.mgclothViewer.canvasStats(s), sel);

  const { url, child } = await view(runDir);
  servers.push(child);

  for (const source of glb ? ['glb', 'obj'] : ['obj']) {
    await page.goto(`${url}?source=${source}`);
    await ready();
    let s = await state();
    check(!s.error && s.kind === 'run' && s.source === source, `${source}: the run loads (${s.error ?? s.kind})`);
    check(s.frameCount === 7 && s.vertices === 100, `${source}: 7 frames of 100 vertices (got ${s.frameCount}, ${s.vertices})`);
    const shaded = await stats();
    check(shaded.std > 8 && shaded.colors > 50, `${source}: the 3D view is drawn (std ${shaded.std.toFixed(1)}, ${shaded.colors} colours)`);

    // Play: frames must advance on their own, then pause.
    const before = s.shown;
    await page.click('#play');
    await page.waitForFunction((n) => window.mgclothViewer.state.shown >= n, before + 4, { timeout: 15000 });
    s = await state();
    check(s.playing && s.shown >= before + 4, `${source}: playing advances frames (${s.shown - before} shown)`);
    await page.click('#play');
    check(!(await state()).playing, `${source}: pause`);

    // Scrub to frame 2, then draw the wireframe.
    await page.$eval('#scrub', (el) => { el.value = '2'; el.dispatchEvent(new Event('input')); });
    await page.waitForFunction(() => window.mgclothViewer.state.frameIndex === 2, null, { timeout: 5000 });
    const label = await page.textContent('#frame-label');
    check(/frame 2 \/ 6/.test(label), `${source}: scrubbing shows frame 2 ("${label.trim()}")`);
    const shaded2 = await stats();
    await page.selectOption('#mode', 'wire');
    const wire = await stats();
    check((await state()).mode === 'wire' && Math.abs(wire.mean - shaded2.mean) > 0.2 && wire.std > 5,
          `${source}: wireframe draws differently (mean ${shaded2.mean.toFixed(1)} -> ${wire.mean.toFixed(1)})`);
  }

  // One cloth is drawn in one tint: nothing warm.
  const single = await stats();
  check(single.cool > 0.01 && single.warm < 0.002,
        `one cloth, one tint (warm ${single.warm.toFixed(4)}, cool ${single.cool.toFixed(4)})`);

  // Stats beside the animation: one plot per column, each drawn.
  const columns = await page.$$eval('#side canvas', (cs) => cs.map((c) => c.dataset.column));
  check(columns.join() === 'iterations,energy,wall_ms', `stats plots: ${columns.join(', ')}`);
  for (const c of columns) {
    const st = await stats(`#side canvas[data-column="${c}"]`);
    check(st.std > 5, `stats plot ${c} is drawn (std ${st.std.toFixed(1)})`);
  }

  check(errors.length === 0, `no page errors (${errors.join('; ') || 'none'})`);

  // Two cloths: each in its own colour, from surfaces.json (the left bluish, the right orange).
  const layers = await view(layersDir);
  servers.push(layers.child);
  await page.goto(layers.url);
  await ready();
  const ls = await state();
  const two = await stats();
  check(!ls.error && ls.surfaces?.join() === 'left,right' && two.warm > 0.01 && two.cool > 0.01,
        `two cloths in two colours (${ls.error ?? ls.surfaces?.join()}; warm ${two.warm.toFixed(3)}, cool ${two.cool.toFixed(3)})`);

  // The walking body of an OBJ-only run: drawn, and posed at the frame shown, as the run wrote it.
  const walkerView = await view(bodyDir);
  servers.push(walkerView.child);
  const bodyErrors = errors.length;
  await page.goto(walkerView.url);
  await ready();
  const ws = await state();
  const described = JSON.parse(fs.readFileSync(path.join(bodyDir, 'obstacles.json'), 'utf8')).meshes[0];
  const bodyInfo = async () => (await page.evaluate(() => window.mgclothViewer.obstacles())).find((o) => o.name === 'body');
  let bi = await bodyInfo();
  check(!ws.error && ws.source === 'obj' && ws.obstacles?.includes('body') && bi?.visible &&
        bi.vertices === described.vertices[1] && bi.triangles === described.triangles,
        `obj run: the walking body is drawn (${ws.error ?? ws.obstacles?.join()}; ${bi?.vertices} vertices, ` +
        `${bi?.triangles} triangles, obstacles.json ${described.vertices[1]}, ${described.triangles})`);
  const withBody = await stats();
  await page.evaluate(() => window.mgclothViewer.showObstacles(false));
  const withoutBody = await stats();
  await page.evaluate(() => window.mgclothViewer.showObstacles(true));
  check(Math.abs(withBody.mean - withoutBody.mean) > 1,
        `obj run: the body shows in the picture (mean ${withBody.mean.toFixed(1)} with, ${withoutBody.mean.toFixed(1)} without)`);
  // Scrubbed to frame 3, the body is where obstacles_00003.bin has it.
  const box0 = await bodyInfo();
  await page.evaluate(() => window.mgclothViewer.seek(3));
  bi = await bodyInfo();
  const bin = fs.readFileSync(path.join(bodyDir, 'obstacles_00003.bin'));
  const xyz = new Float32Array(bin.buffer, bin.byteOffset, bin.byteLength / 4);
  const lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity];
  for (let i = described.vertices[0]; i < described.vertices[0] + described.vertices[1]; ++i)
    for (let c = 0; c < 3; ++c) { lo[c] = Math.min(lo[c], xyz[3 * i + c]); hi[c] = Math.max(hi[c], xyz[3 * i + c]); }
  const off = Math.max(...[0, 1, 2].flatMap((c) => [Math.abs(bi.min[c] - lo[c]), Math.abs(bi.max[c] - hi[c])]));
  const moved = Math.max(...[0, 1, 2].map((c) => Math.abs(bi.max[c] - box0.max[c])));
  check((await state()).frameNumber === 3 && off < 1e-6 && moved > 0.005,
        `obj run: at frame 3 the body is posed from obstacles_00003.bin (off by ${off.toExponential(1)} m, ` +
        `moved ${moved.toFixed(3)} m since frame 0)`);
  check(errors.length === bodyErrors, `obj run with the body: no page errors (${errors.slice(bodyErrors).join('; ') || 'none'})`);

  // A frame that is not there is an error the page says.
  await page.goto(`${url}?frame=99`);
  await ready();
  const missing = (await state()).error || '';
  check(/frame 99 is not in/.test(missing), `?frame=99 is refused ("${missing}")`);

  // A bench folder: the convergence plot.
  const bench = await view(benchDir);
  servers.push(bench.child);
  await page.goto(bench.url);
  await ready();
  const b = await state();
  const plot = await stats('#side canvas[data-column="rel_energy_error"]');
  check(!b.error && b.kind === 'convergence' && plot.std > 5, `bench folder: convergence plot drawn (std ${plot?.std.toFixed(1)})`);

  check(refused.length === 0, `no request outside 127.0.0.1 (${refused.join(', ') || 'none'})`);

  // `mgcloth render`: a picture of frame 3 that is not blank, at the size asked for.
  const png = path.join(work, 'frame3.png');
  const r = run(['render', runDir, '--frame', '3', '--out', png, '--width', '320', '--height', '200'], { allowFail: true });
  check(r.status === 0 && fs.existsSync(png), `render writes ${path.basename(png)} (${(r.stdout + r.stderr).trim()})`);
  if (fs.existsSync(png)) {
    const img = await page.evaluate(async (b64) => {
      const im = new Image();
      im.src = `data:image/png;base64,${b64}`;
      await im.decode();
      const c = document.createElement('canvas');
      c.width = im.width; c.height = im.height;
      c.id = 'decoded';
      document.body.appendChild(c);
      c.getContext('2d').drawImage(im, 0, 0);
      return { width: im.width, height: im.height };
    }, fs.readFileSync(png).toString('base64'));
    const st = await stats('#decoded');
    check(img.width === 320 && img.height === 200 && st.std > 8 && st.colors > 50,
          `render's picture is ${img.width}x${img.height} and not blank (std ${st.std.toFixed(1)}, ${st.colors} colours)`);
  }
  const bad = run(['render', runDir, '--frame', '99', '--out', path.join(work, 'x.png')], { allowFail: true });
  check(bad.status === 1 && /99/.test(bad.stderr), `render --frame 99 fails naming the frame (${bad.stderr.trim()})`);
} finally {
  await browser.close();
  for (const c of servers) {
    const code = await stop(c);
    check(code === 0, `mgcloth view stops on Ctrl-C with exit 0 (got ${code})`);
  }
}

console.log(failures ? `${failures} check(s) failed` : 'all checks passed');
process.exit(failures ? 1 : 0);
