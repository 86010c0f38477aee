// 3-D skeleton viewer: the original and the retimed motion side by side (three.js, WebGL).
import * as THREE from "three";
import { OrbitControls } from "three/examples/jsm/controls/OrbitControls.js";

const UP = new THREE.Vector3(0, 1, 0);

export class Viewer {
  constructor(container, skeleton, positions, nFrames, quality = {}) {
    this.container = container;
    this.parents = skeleton.parents;
    this.nPoints = skeleton.n_points;
    this.positions = positions; // Float32Array (F * P * 3), metres, y up
    this.nFrames = nFrames;
    this.bones = [];
    this.parents.forEach((p, i) => { if (p >= 0) this.bones.push([p, i]); });
    this.follow = true;
    this._analyse();

    const q = (this.quality = { antialias: true, shadows: true, pixelRatio: Math.min(window.devicePixelRatio || 1, 2), ...quality });
    this.renderer = new THREE.WebGLRenderer({ antialias: q.antialias, alpha: false, preserveDrawingBuffer: !!q.preserve });
    this.renderer.setPixelRatio(q.pixelRatio);
    this.renderer.shadowMap.enabled = q.shadows;
    this.renderer.shadowMap.type = THREE.PCFShadowMap;
    this.renderer.setClearColor(0x151b22);
    container.appendChild(this.renderer.domElement);

    const scene = (this.scene = new THREE.Scene());
    scene.fog = q.lite ? new THREE.Fog(0x151b22, 5, 14) : new THREE.Fog(0x151b22, 10, 26);
    this.camera = new THREE.PerspectiveCamera(40, 1, 0.05, 200);
    this.controls = new OrbitControls(this.camera, this.renderer.domElement);
    this.controls.enableDamping = true;
    this.controls.maxPolarAngle = Math.PI * 0.495;
    this.onChange = null;
    this.controls.addEventListener("change", () => { if (this.onChange && !this._rendering) this.onChange(); });

    scene.add(new THREE.HemisphereLight(0xdfe8f5, 0x28303a, 1.6));
    const sun = (this.sun = new THREE.DirectionalLight(0xffffff, 2.2));
    sun.position.set(3, 7, 4);
    sun.castShadow = true;
    sun.shadow.mapSize.set(1024, 1024);
    Object.assign(sun.shadow.camera, { left: -4, right: 4, top: 4, bottom: -4, near: 0.5, far: 25 });
    scene.add(sun, sun.target);

    const ground = new THREE.Mesh(new THREE.PlaneGeometry(200, 200),
      q.lite ? new THREE.MeshBasicMaterial({ color: 0x1a2028 }) : new THREE.MeshStandardMaterial({ color: 0x1a2028, roughness: 0.95, metalness: 0 }));
    ground.rotation.x = -Math.PI / 2;
    ground.position.y = this.floor;
    ground.receiveShadow = true;
    scene.add(ground);
    // a 1 m grid around the characters (it moves with them in whole metres, so it looks fixed)
    const grid = (this.grid = new THREE.GridHelper(30, 30, 0x2d3844, 0x262f3a));
    grid.position.y = this.floor + 0.001;
    scene.add(grid);

    this.figures = [this._figure(0x7fa6d9), this._figure(0xf5a524)];
    this.figures.forEach((f) => scene.add(f.group));
    this._placeCamera();

    this._resize = () => this.resize();
    new ResizeObserver(this._resize).observe(container);
    this.resize();
  }

  // Travel direction, floor height and side-by-side offset from the whole clip.
  _analyse() {
    const P = this.nPoints, pos = this.positions, F = this.nFrames;
    let minY = Infinity, maxY = -Infinity;
    for (let k = 1; k < pos.length; k += 3) { minY = Math.min(minY, pos[k]); maxY = Math.max(maxY, pos[k]); }
    this.floor = minY;
    this.height = Math.max(0.5, maxY - minY);
    const r0 = new THREE.Vector3(pos[0], 0, pos[2]);
    const last = (F - 1) * P * 3;
    const r1 = new THREE.Vector3(pos[last], 0, pos[last + 2]);
    const travel = r1.clone().sub(r0);
    this.travel = travel.length() > 0.3 ? travel.normalize() : new THREE.Vector3(1, 0, 0);
    const side = new THREE.Vector3().crossVectors(UP, this.travel).normalize();
    // spread the two figures by about a body height, or more when the motion sways sideways
    let sway = 0;
    for (let f = 0; f < F; f++) {
      const o = f * P * 3;
      sway = Math.max(sway, Math.abs((pos[o] - pos[0]) * side.x + (pos[o + 2] - pos[2]) * side.z));
    }
    this.offset = side.multiplyScalar(Math.max(0.9 * this.height, 2 * sway + 0.6 * this.height) / 2);
    this.center = new THREE.Vector3();
    for (let f = 0; f < F; f++) { const o = f * P * 3; this.center.x += pos[o]; this.center.z += pos[o + 2]; }
    this.center.multiplyScalar(1 / F);
    this.center.y = this.floor + 0.5 * this.height;
  }

  _figure(color) {
    const group = new THREE.Group();
    const bone = new THREE.CylinderGeometry(1, 1, 1, 10, 1, false);
    bone.translate(0, 0.5, 0);
    const mat = this.quality.lite ? new THREE.MeshLambertMaterial({ color })
      : new THREE.MeshStandardMaterial({ color, roughness: 0.55, metalness: 0.05 });
    const bones = new THREE.InstancedMesh(bone, mat, this.bones.length);
    const joints = new THREE.InstancedMesh(new THREE.SphereGeometry(1, 14, 10), mat, this.nPoints);
    for (const m of [bones, joints]) { m.castShadow = true; m.frustumCulled = false; group.add(m); }
    return { group, bones, joints, radius: Math.max(0.014, 0.017 * this.height) };
  }

  _placeCamera() {
    // in front of the pair, looking back along the travel direction, a little from above:
    // the original stands on the left, the retimed motion on the right
    const dist = 1.7 * this.height + 1.9 * this.offset.length();
    const eye = this.center.clone().addScaledVector(this.travel, dist);
    eye.y = this.center.y + 0.3 * dist;
    this.camera.position.copy(eye);
    this.controls.target.copy(this.center);
    this.controls.update();
    this.lastFocus = this.center.clone();
  }

  resize() {
    const w = this.container.clientWidth || 1, h = this.container.clientHeight || 1;
    this.renderer.setSize(w, h, false);
    this.camera.aspect = w / h;
    this.camera.updateProjectionMatrix();
    if (this.onChange) this.onChange();
  }

  // Pose of figure k at fractional source frame u.
  _pose(k, u) {
    const P = this.nPoints, pos = this.positions, F = this.nFrames;
    u = Math.min(Math.max(u, 0), F - 1);
    const f0 = Math.min(Math.floor(u), F - 2 >= 0 ? F - 2 : 0), w = u - f0, f1 = Math.min(f0 + 1, F - 1);
    const out = new Float32Array(P * 3);
    const a = f0 * P * 3, b = f1 * P * 3;
    const side = k === 0 ? -1 : 1;
    for (let i = 0; i < P * 3; i++) out[i] = pos[a + i] + w * (pos[b + i] - pos[a + i]);
    for (let i = 0; i < P; i++) { out[3 * i] += side * this.offset.x; out[3 * i + 2] += side * this.offset.z; }
    return out;
  }

  // The clip's own contact forces (retime check, per source frame: body weights and metres, y up)
  // as arrows on the original figure: one per foot at its centre of pressure, and the residual
  // force (what no contact gives) at the centre of mass; one body weight is half the body's height.
  setCheck(check) {
    this.check = check;
    this.forceLength = 0.5 * this.height;
    const r = 0.012 * this.height;
    const make = (color) => {
      // a solid arrow drawn over the figures: a unit shaft along +y and a head, scaled per frame
      const mat = new THREE.MeshBasicMaterial({ color, depthTest: false, transparent: true, opacity: 0.9 });
      const shaft = new THREE.Mesh(new THREE.CylinderGeometry(r, r, 1, 8).translate(0, 0.5, 0), mat);
      const head = new THREE.Mesh(new THREE.ConeGeometry(2.6 * r, 1, 12).translate(0, -0.5, 0), mat);
      const a = new THREE.Group();
      a.add(shaft, head);
      a.renderOrder = 10;
      shaft.renderOrder = head.renderOrder = 10;
      a.visible = false;
      a.setLength = (len) => {
        const h = Math.min(8 * r, 0.4 * len);
        shaft.scale.set(1, Math.max(len - h, 1e-4), 1);
        head.scale.set(1, h, 1);
        head.position.y = len;
      };
      a.setDirection = (dir) => a.quaternion.setFromUnitVectors(UP, dir);
      this.scene.add(a);
      return a;
    };
    this.arrows = { left: make(0x4cc3ff), right: make(0x9be564), residual: make(0xff4d4d) };
  }

  _showForces(u) {
    if (!this.check) return;
    const f = Math.min(Math.max(Math.round(u), 0), this.check.residual.length - 1);
    const shift = this.offset.clone().multiplyScalar(-1); // the original stands on the left
    const place = (arrow, force, at) => {
      const v = new THREE.Vector3().fromArray(force), len = v.length();
      arrow.visible = len > 0.02;
      arrow.userData.length = len * this.forceLength;
      if (!arrow.visible) return;
      arrow.position.fromArray(at).add(shift);
      arrow.setDirection(v.multiplyScalar(1 / len));
      arrow.setLength(len * this.forceLength);
    };
    for (const foot of ["left", "right"]) place(this.arrows[foot], this.check.feet[foot].force[f], this.check.feet[foot].point[f]);
    place(this.arrows.residual, this.check.residual_force[f], this.check.com[f]);
    this.shownForces = { frame: f, ...Object.fromEntries(Object.entries(this.arrows).map(([k, a]) => [k, a.visible
      ? { origin: a.position.toArray(), direction: new THREE.Vector3(0, 1, 0).applyQuaternion(a.quaternion).toArray(), length: a.userData.length }
      : null])) };
  }

  // Draw: original at source frame uOrig, retimed at source frame uRetimed.
  show(uOrig, uRetimed) {
    const poses = [this._pose(0, uOrig), this._pose(1, uRetimed)];
    this._showForces(uOrig);
    const m = new THREE.Matrix4(), q = new THREE.Quaternion(), a = new THREE.Vector3(), b = new THREE.Vector3();
    const d = new THREE.Vector3(), s = new THREE.Vector3();
    poses.forEach((pose, k) => {
      const fig = this.figures[k], r = fig.radius;
      this.bones.forEach(([p, i], n) => {
        a.fromArray(pose, 3 * p); b.fromArray(pose, 3 * i);
        d.subVectors(b, a);
        const len = d.length();
        q.setFromUnitVectors(UP, len > 1e-9 ? d.multiplyScalar(1 / len) : UP);
        m.compose(a, q, s.set(r * 0.75, len, r * 0.75));
        fig.bones.setMatrixAt(n, m);
      });
      for (let i = 0; i < this.nPoints; i++) {
        a.fromArray(pose, 3 * i);
        const rr = this.parents[i] < 0 ? 1.6 * r : r * 1.15;
        m.compose(a, q.identity(), s.set(rr, rr, rr));
        fig.joints.setMatrixAt(i, m);
      }
      fig.bones.instanceMatrix.needsUpdate = true;
      fig.joints.instanceMatrix.needsUpdate = true;
    });
    this.lastPoses = poses;
    if (this.follow) {
      const focus = new THREE.Vector3((poses[0][0] + poses[1][0]) / 2, this.center.y, (poses[0][2] + poses[1][2]) / 2);
      const delta = focus.clone().sub(this.lastFocus);
      this.camera.position.add(delta);
      this.controls.target.add(delta);
      this.lastFocus = focus;
    }
    this.grid.position.x = Math.round(this.controls.target.x);
    this.grid.position.z = Math.round(this.controls.target.z);
    this.sun.position.set(this.controls.target.x + 3, 7, this.controls.target.z + 4);
    this.sun.target.position.copy(this.controls.target);
    this._rendering = true;
    const moving = this.controls.update(); // true while damping still moves the camera
    this._rendering = false;
    this.renderer.render(this.scene, this.camera);
    if (moving && this.onChange) this.onChange();
  }
}

// Which WebGL the browser offers: null (none), or {software: bool, renderer: string}.
export function probeWebGL() {
  try {
    const c = document.createElement("canvas");
    const gl = c.getContext("webgl2") || c.getContext("webgl");
    if (!gl) return null;
    const ext = gl.getExtension("WEBGL_debug_renderer_info");
    const renderer = String(ext ? gl.getParameter(ext.UNMASKED_RENDERER_WEBGL) : gl.getParameter(gl.RENDERER));
    const lose = gl.getExtension("WEBGL_lose_context");
    if (lose) lose.loseContext();
    return { renderer, software: /swiftshader|llvmpipe|softpipe|software|basic render/i.test(renderer) };
  } catch (e) {
    return null;
  }
}
