// The obstacles of scene.resolved.json as meshes posed at any time, for runs without animation.glb. Shapes and
// motions follow docs/scene-format.md: shapes in the obstacle's local frame, R = Rz·Ry·Rx from rotation_deg,
// constant_velocity R(t) = exp(ω t)·R₀, keyframes linear in position and slerped in rotation, held outside the keys.
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
