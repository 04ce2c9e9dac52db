// The obstacles of a run without animation.glb. Shapes (buildObstacles) come from scene.resolved.json, posed at any
// time; shapes and motions follow docs/scene-format.md: shapes in the obstacle's local frame, R = Rz·Ry·Rx from
// rotation_deg, constant_velocity R(t) = exp(ω t)·R₀, keyframes linear in position and slerped in rotation, held
// outside the keys. Triangle meshes (MeshObstacles: a walking body, OBJ sequences, glTF skins, OBJ files) come from
// the frames of them that the run wrote beside its OBJ frames (obstacles.json, obstacles_NNNNN.bin).
import * as THREE from 'three';

const DEG = Math.PI / 180;

function quatFromDeg(r) {
  // three.js order 'ZYX' is the matrix Rz·Ry·Rx.
  return new THREE.Quaternion().setFromEuler(new THREE.Euler(r[0] * DEG, r[1] * DEG, r[2] * DEG, 'ZYX'));
}

function poseAt(o, t) {
  const p0 = new THREE.Vector3(...(o.position || [0, 0, 0]));
  const q0 = quatFromDeg(o.rotation_deg || [0, 0, 0]);
  const m = o.motion || { type: 'static' };
  if (m.type === 'constant_velocity') {
    const p = p0.clone().addScaledVector(new THREE.Vector3(...(m.linear_velocity || [0, 0, 0])), t);
    const w = new THREE.Vector3(...(m.angular_velocity || [0, 0, 0]));
    const angle = w.length() * t;
    const q = angle > 0 ? new THREE.Quaternion().setFromAxisAngle(w.normalize(), angle).multiply(q0) : q0;
    return { p, q };
  }
  if (m.type === 'keyframes' && m.keys?.length) {
    const key = (k) => ({ p: new THREE.Vector3(...(k.position || o.position || [0, 0, 0])),
                          q: quatFromDeg(k.rotation_deg || o.rotation_deg || [0, 0, 0]) });
    const keys = m.keys;
    if (t <= keys[0].time) return key(keys[0]);
    if (t >= keys[keys.length - 1].time) return key(keys[keys.length - 1]);
    let i = 0;
    while (keys[i + 1].time < t) ++i;
    const a = key(keys[i]), b = key(keys[i + 1]);
    const s = (t - keys[i].time) / (keys[i + 1].time - keys[i].time);
    return { p: a.p.lerp(b.p, s), q: a.q.slerp(b.q, s) };
  }
  return { p: p0, q: q0 };
}

/**
 * @param {object[]} obstacles scene.resolved.json's obstacles
 * @param {THREE.Box3} clothBox where the cloth is, to size the finite square drawn for an infinite plane
 * @returns {{meshes: THREE.Mesh[], setTime: (t: number) => void}}
 */
export function buildObstacles(obstacles, clothBox, material) {
  const meshes = [];
  const center = clothBox.getCenter(new THREE.Vector3());
  const extent = Math.max(clothBox.getSize(new THREE.Vector3()).length(), 0.5);
  for (const o of obstacles || []) {
    const s = o.shape || {};
    let geometry;
    if (s.type === 'sphere') {
      geometry = new THREE.SphereGeometry(s.radius, 64, 32);
    } else if (s.type === 'box') {
      const h = s.half_extents || [0.5, 0.5, 0.5];
      geometry = new THREE.BoxGeometry(2 * h[0], 2 * h[1], 2 * h[2]);
    } else if (s.type === 'capsule') {
      geometry = new THREE.CapsuleGeometry(s.radius, 2 * (s.half_length ?? 0.25), 12, 48);
      geometry.rotateX(Math.PI / 2);  // three's capsule runs along y, mgcloth's along local z
    } else if (s.type === 'plane') {
      // The half-space z < 0: its surface as a square under the cloth, 3 cloth diagonals wide.
      const { p, q } = poseAt(o, 0);
      const local = center.clone().sub(p).applyQuaternion(q.clone().invert());
      geometry = new THREE.PlaneGeometry(3 * extent, 3 * extent);
      geometry.translate(local.x, local.y, 0);
    } else {
      continue;
    }
    const mesh = new THREE.Mesh(geometry, material);
    mesh.name = o.name || s.type;
    mesh.userData.obstacle = o;
    mesh.userData.plane = s.type === 'plane';
    meshes.push(mesh);
  }
  const setTime = (t) => {
    for (const mesh of meshes) {
      const { p, q } = poseAt(mesh.userData.obstacle, t);
      mesh.position.copy(p);
      mesh.quaternion.copy(q);
    }
  };
  setTime(0);
  return { meshes, setTime };
}

async function fetchOk(url) {
  const r = await fetch(url);
  if (!r.ok) throw new Error(`${url}: HTTP ${r.status}`);
  return r;
}

/**
 * The triangle-mesh obstacles of a run that wrote OBJ frames (a walking body, OBJ sequences, glTF skins, static
 * meshes): obstacles.json gives each mesh's name, its range of the vertices and its triangles; obstacles_NNNNN.bin,
 * written with frame_NNNNN.obj, the world positions of all their vertices at that frame (float32 x, y, z).
 */
export class MeshObstacles {
  /** @param {string} base URL of the folder; @param {Set<string>} names its files */
  static async open(base, names, material) {
    const s = new MeshObstacles();
    s.base = base;
    const j = await (await fetchOk(base + 'obstacles.json')).json();
    const total = j.vertices;
    if (!Number.isInteger(total) || total < 0 || !Array.isArray(j.meshes))
      throw new Error('obstacles.json: no "vertices" count and "meshes" list');
    s.numVertices = total;
    s.meshes = j.meshes.map((m, k) => {
      const [first, count] = m.vertices || [];
      if (!Number.isInteger(first) || !Number.isInteger(count) || first < 0 || first + count > total)
        throw new Error(`obstacles.json: meshes[${k}] ("${m.name}"): vertices [${m.vertices}] outside the ${total} vertices`);
      const index = Uint32Array.from(m.indices || []);
      if (index.length % 3 || index.some((i) => i >= count))
        throw new Error(`obstacles.json: meshes[${k}] ("${m.name}"): indices are not triangles of its ${count} vertices`);
      const geometry = new THREE.BufferGeometry();
      geometry.setAttribute('position', new THREE.BufferAttribute(new Float32Array(3 * count), 3));
      geometry.setIndex(new THREE.BufferAttribute(index, 1));
      const mesh = new THREE.Mesh(geometry, material);
      mesh.name = m.name || `obstacle ${m.obstacle ?? k}`;
      mesh.userData.range = [first, count];
      mesh.userData.obstacleIndex = m.obstacle;
      mesh.visible = false;  // until a frame of positions is set
      return mesh;
    });
    // The frames there are; a frame without its own file (none was written for it) shows the latest before it.
    s.numbers = [...names].map((n) => /^obstacles_(\d{5})\.bin$/.exec(n)).filter(Boolean)
      .map((m) => parseInt(m[1], 10)).sort((a, b) => a - b);
    s.cache = new Map();
    s.loaded = new Set();
    return s;
  }

  /** The number of the file that holds frame `number`'s positions, or null when there is none. */
  fileFor(number) {
    let best = null;
    for (const k of this.numbers) if (k <= number) best = k; else break;
    return best;
  }

  isLoaded(number) {
    const f = this.fileFor(number);
    return f === null || this.loaded.has(f);
  }

  /** Positions of every vertex at frame `number` (a promise; null when no file holds them). */
  positions(number) {
    const f = this.fileFor(number);
    if (f === null) return Promise.resolve(null);
    if (!this.cache.has(f)) {
      const file = `obstacles_${String(f).padStart(5, '0')}.bin`;
      this.cache.set(f, fetchOk(this.base + file).then((r) => r.arrayBuffer()).then((buf) => {
        if (buf.byteLength !== 12 * this.numVertices)
          throw new Error(`${file}: ${buf.byteLength} bytes, but obstacles.json has ${this.numVertices} vertices (12 bytes each)`);
        this.loaded.add(f);
        return new Float32Array(buf);
      }).catch((e) => { this.cache.delete(f); throw e; }));
    }
    return this.cache.get(f);
  }

  /** Poses the meshes as at frame `number`; hides them when no file holds that frame. */
  async setFrame(number) {
    const p = await this.positions(number);
    for (const mesh of this.meshes) {
      mesh.visible = p !== null;
      if (!p) continue;
      const [first, count] = mesh.userData.range;
      const g = mesh.geometry;
      g.attributes.position.array.set(p.subarray(3 * first, 3 * (first + count)));
      g.attributes.position.needsUpdate = true;
      g.computeVertexNormals();
      g.computeBoundingBox();
      g.computeBoundingSphere();
    }
  }
}
