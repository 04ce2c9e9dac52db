// The two sources of a run's frames: the frame_NNNNN.obj files, or animation.glb (cloth as morph targets, obstacles
// as animated nodes). Both give one triangle topology and, per frame, world positions in simulation coordinates
// (z up, metres), so the page draws them the same way.
import * as THREE from 'three';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';

async function fetchOk(url) {
  const r = await fetch(url);
  if (!r.ok) throw new Error(`${url}: HTTP ${r.status}`);
  return r;
}

/** Positions, material coordinates and triangles of one OBJ file as mgcloth writes it (v, vt, f a/b ...). */
function parseObj(text, wantTopology) {
  const v = [], vt = [], tris = [];
  let uvOf = null;
  for (const line of text.split('\n')) {
    if (line.startsWith('v ')) {
      const f = line.split(/\s+/);
      v.push(+f[1], +f[2], +f[3]);
    } else if (!wantTopology) {
      continue;
    } else if (line.startsWith('vt ')) {
      const f = line.split(/\s+/);
      vt.push(+f[1], +f[2]);
    } else if (line.startsWith('f ')) {
      const corners = line.trim().split(/\s+/).slice(1).map((c) => c.split('/').map((s) => (s ? parseInt(s, 10) : 0)));
      const nv = v.length / 3;
      const idx = corners.map(([a]) => (a < 0 ? nv + a : a - 1));
      uvOf ??= new Map();
      corners.forEach(([, t], i) => {
        if (t && !uvOf.has(idx[i])) uvOf.set(idx[i], t < 0 ? vt.length / 2 + t : t - 1);
      });
      for (let i = 1; i + 1 < idx.length; ++i) tris.push(idx[0], idx[i], idx[i + 1]);  // polygons as fans
    }
  }
  const positions = new Float32Array(v);
  if (!wantTopology) return { positions };
  const n = positions.length / 3;
  let uv = null;
  if (vt.length && uvOf) {
    uv = new Float32Array(2 * n);
    for (const [vi, ti] of uvOf) { uv[2 * vi] = vt[2 * ti]; uv[2 * vi + 1] = vt[2 * ti + 1]; }
  }
  return { positions, uv, index: new Uint32Array(tris) };
}

export class ObjFrames {
  /** @param {string} base URL of the folder; @param {string[]} files frame_NNNNN.obj names, sorted */
  static async open(base, files, timeStep) {
    const s = new ObjFrames();
    s.kind = 'obj';
    s.base = base;
    s.frames = files.map((file) => {
      const number = parseInt(file.slice(6, 11), 10);
      return { number, time: number * timeStep, file };
    });
    s.cache = new Map();
    const first = parseObj(await (await fetchOk(base + files[0])).text(), true);
    if (first.positions.length === 0 || first.index.length === 0) throw new Error(`${files[0]}: no triangles`);
    s.numVertices = first.positions.length / 3;
    s.index = first.index;
    s.uv = first.uv;
    s.cache.set(0, Promise.resolve(first.positions));
    s.loaded = new Set([0]);
    return s;
  }

  isLoaded(k) { return this.loaded.has(k); }

  positions(k) {
    if (!this.cache.has(k)) {
      const f = this.frames[k];
      this.cache.set(k, fetchOk(this.base + f.file).then((r) => r.text()).then((text) => {
        const p = parseObj(text, false).positions;
        if (p.length !== 3 * this.numVertices)
          throw new Error(`${f.file}: ${p.length / 3} vertices, but ${this.frames[0].file} has ${this.numVertices}`);
        this.loaded.add(k);
        return p;
      }).catch((e) => { this.cache.delete(k); throw e; }));
    }
    return this.cache.get(k);
  }
}

function attributeArray(attr) {
  const out = new Float32Array(attr.count * attr.itemSize);
  for (let i = 0; i < attr.count; ++i) for (let c = 0; c < attr.itemSize; ++c) out[i * attr.itemSize + c] = attr.getComponent(i, c);
  return out;
}

export class GlbFrames {
  static async open(url, timeStep) {
    const gltf = await new GLTFLoader().loadAsync(url);
    const s = new GlbFrames();
    s.kind = 'glb';
    s.root = gltf.scene;
    // mgcloth's file turns its z-up world into glTF's y-up under one root node; the page works in z-up, so
    // that turn is undone. Another file's content is y-up: turn it to z-up as a whole.
    const zUp = gltf.scene.getObjectByName('z_up');
    if (zUp) zUp.quaternion.identity();
    else gltf.scene.rotation.x = Math.PI / 2;
    gltf.scene.updateMatrixWorld(true);

    let cloth = null;
    gltf.scene.traverse((o) => { if (!cloth && o.isMesh && o.geometry.morphAttributes.position) cloth = o; });
    if (!cloth) gltf.scene.traverse((o) => { if (!cloth && o.isMesh && o.name === 'cloth') cloth = o; });
    if (!cloth) throw new Error('animation.glb: no cloth mesh (a mesh with morph targets)');
    const g = cloth.geometry;
    s.base = attributeArray(g.attributes.position);
    s.numVertices = g.attributes.position.count;
    s.targets = (g.morphAttributes.position || []).map(attributeArray);
    s.uv = g.attributes.uv ? attributeArray(g.attributes.uv) : null;
    s.index = g.index ? Uint32Array.from(g.index.array) : Uint32Array.from({ length: s.numVertices }, (_, i) => i);
    cloth.parent.remove(cloth);  // the page draws the cloth itself, with normals recomputed per frame

    // The frames are the keys of the weights channel: at frame k's time the target of frame k has weight 1. Its
    // weights are applied here on the CPU rather than by morphTargetInfluences, since the GPU path bounds the
    // number of targets (uniform and texture-layer limits) that a long run exceeds, and has no normals to morph.
    const clip = gltf.animations[0];
    const weights = clip?.tracks.find((t) => t.name.endsWith('.morphTargetInfluences'));
    const names = Object.entries(cloth.morphTargetDictionary || {}).sort((a, b) => a[1] - b[1]).map(([n]) => n);
    const numberOf = (j) => {
      const m = /(\d+)$/.exec(names[j] || '');
      return m ? parseInt(m[1], 10) : null;
    };
    s.frames = [];
    s.weights = [];
    const nt = s.targets.length;
    if (weights) {
      for (let i = 0; i < weights.times.length; ++i) {
        const row = Array.from(weights.values.slice(i * nt, (i + 1) * nt));
        const t = weights.times[i];
        const on = row.findIndex((w) => w > 0.5);
        s.frames.push({ number: (on >= 0 ? numberOf(on) : null) ?? Math.round(t / timeStep), time: t });
        s.weights.push(row);
      }
    } else {
      s.frames.push({ number: 0, time: 0 });
      s.weights.push(new Array(nt).fill(0));
    }

    // Obstacles: every other mesh, moved by the remaining (translation, rotation) channels.
    s.obstacles = [];
    gltf.scene.traverse((o) => { if (o.isMesh) s.obstacles.push(o); });
    const others = clip ? clip.tracks.filter((t) => t !== weights) : [];
    if (others.length) {
      s.mixer = new THREE.AnimationMixer(gltf.scene);
      s.mixer.clipAction(new THREE.AnimationClip('obstacles', clip.duration, others)).play();
    }
    return s;
  }

  isLoaded() { return true; }

  positions(k) {
    // glTF morph targets are displacements from the base positions (GLTFLoader: morphTargetsRelative).
    const p = Float32Array.from(this.base);
    this.weights[k].forEach((w, j) => {
      if (w === 0) return;
      const t = this.targets[j];
      for (let i = 0; i < p.length; ++i) p[i] += w * t[i];
    });
    return Promise.resolve(p);
  }

  /** Poses the obstacles as at frame k. */
  setFrame(k) {
    if (this.mixer) this.mixer.setTime(this.frames[k].time);
  }
}
