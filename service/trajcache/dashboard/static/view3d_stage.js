// The 3D view's stage: a three.js WebGL renderer, a z-up camera with orbit controls, lights,
// a floor grid, and the shapes the service describes (primitives by size, meshes as triangles).
// Renders on demand: after a change, never in a loop of its own.
import * as THREE from "three";
import { OrbitControls } from "three/addons/controls/OrbitControls.js";
import { STLLoader } from "three/addons/loaders/STLLoader.js";

export const COLORS = {
  background: 0xf6f8fa,
  robot: 0xf28c28, // orange: nothing else on the stage is
  scene: 0x8ea4bd,
  highlight: 0xff00ff, // magenta, unlit: the link and the object at fault
  path: 0x1f6feb,
  base: 0x57606a,
  lines: 0x1a7f37, // green: a Cartesian path's straight lines, as asked
};

const MARKER_M = 0.12; // the length of a goal frame's axes
const AXES = [[0xff0000, [0, 0, -Math.PI / 2]], [0x00c000, [0, 0, 0]], [0x0050ff, [Math.PI / 2, 0, 0]]];

// Three axes (x red, y green, z blue: unlit rods, thick enough to see) at a pose: x, y, z and a
// quaternion x, y, z, w.
export function frameMarker(position, orientation) {
  const marker = new THREE.Group();
  for (const [color, [rx, ry, rz]] of AXES) {
    const rod = new THREE.CylinderGeometry(0.005, 0.005, MARKER_M, 10);
    rod.translate(0, MARKER_M / 2, 0); // from the origin along +y, then turned onto its axis
    rod.rotateX(rx).rotateZ(rz).rotateY(ry);
    marker.add(new THREE.Mesh(rod, new THREE.MeshBasicMaterial({ color })));
  }
  setPose(marker, [...position, ...orientation]);
  marker.userData.name = "goal pose";
  return marker;
}

// A polyline through poses (7 numbers each), a dot at each corner: drawn over the robot (no
// depth test), since the lines asked for run through the link that follows them.
export function polyline(poses, color) {
  const group = new THREE.Group();
  const points = poses.map((p) => new THREE.Vector3(p[0], p[1], p[2]));
  const line = new THREE.Line(
    new THREE.BufferGeometry().setFromPoints(points),
    new THREE.LineBasicMaterial({ color, depthTest: false, transparent: true }),
  );
  group.add(line);
  const dot = new THREE.MeshBasicMaterial({ color, depthTest: false, transparent: true });
  for (const point of points) {
    const mesh = new THREE.Mesh(new THREE.SphereGeometry(0.008, 12, 8), dot);
    mesh.position.copy(point);
    group.add(mesh);
  }
  for (const child of group.children) child.renderOrder = 1;
  group.userData.name = "waypoints";
  return group;
}

const HEIGHT = 480;

// A shape's geometry in its own frame: cylinders and capsules along local z, as the service
// gives them (three.js builds them along y).
export function primitive(kind, size) {
  let geometry;
  if (kind === "box") geometry = new THREE.BoxGeometry(size[0], size[1], size[2]);
  else if (kind === "sphere") geometry = new THREE.SphereGeometry(size[0], 24, 16);
  else if (kind === "cylinder") geometry = new THREE.CylinderGeometry(size[0], size[0], size[1], 28);
  else if (kind === "capsule") geometry = new THREE.CapsuleGeometry(size[0], size[1], 8, 20);
  else return null;
  if (kind === "cylinder" || kind === "capsule") geometry.rotateX(Math.PI / 2);
  return geometry;
}

export function triangles(vertices, faces) {
  const geometry = new THREE.BufferGeometry();
  geometry.setAttribute("position", new THREE.Float32BufferAttribute(vertices.flat(), 3));
  geometry.setIndex(faces.flat());
  geometry.computeVertexNormals();
  return geometry;
}

export function stlGeometry(buffer) {
  return new STLLoader().parse(buffer);
}

// position (x, y, z) and quaternion (x, y, z, w) from 7 numbers at `offset`
export function setPose(object, values, offset = 0) {
  object.position.set(values[offset], values[offset + 1], values[offset + 2]);
  object.quaternion.set(values[offset + 3], values[offset + 4], values[offset + 5], values[offset + 6]);
}

export function materials() {
  return {
    robot: new THREE.MeshStandardMaterial({ color: COLORS.robot, roughness: 0.55, metalness: 0.05 }),
    scene: new THREE.MeshStandardMaterial({
      color: COLORS.scene, roughness: 0.9, transparent: true, opacity: 0.45, depthWrite: false,
    }),
    faded: new THREE.MeshStandardMaterial({
      color: COLORS.scene, roughness: 0.9, transparent: true, opacity: 0.07, depthWrite: false,
    }),
    highlight: new THREE.MeshBasicMaterial({ color: COLORS.highlight }),
    path: new THREE.LineBasicMaterial({ color: COLORS.path }),
    base: new THREE.LineDashedMaterial({ color: COLORS.base, dashSize: 0.05, gapSize: 0.04 }),
  };
}

export class Stage {
  constructor(container) {
    this.container = container;
    this.renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
    this.renderer.setPixelRatio(1);
    this.renderer.setClearColor(COLORS.background);
    container.appendChild(this.renderer.domElement);
    this.scene = new THREE.Scene();
    this.camera = new THREE.PerspectiveCamera(45, 1, 0.02, 200);
    this.camera.up.set(0, 0, 1);
    this.controls = new OrbitControls(this.camera, this.renderer.domElement);
    this.controls.addEventListener("change", () => this.render());
    this.beforeRender = null; // called before each frame is drawn
    this.scene.add(new THREE.HemisphereLight(0xffffff, 0x8a8f98, 1.6));
    const sun = new THREE.DirectionalLight(0xffffff, 1.8);
    sun.position.set(3, -4, 6);
    this.scene.add(sun);
    const grid = new THREE.GridHelper(20, 40, 0xc4ccd6, 0xdde3ea);
    grid.rotateX(Math.PI / 2); // onto the floor (xy), z up
    this.scene.add(grid);
    this.content = new THREE.Group();
    this.scene.add(this.content);
    this.resize();
    window.addEventListener("resize", () => { this.resize(); this.render(); });
  }

  resize() {
    const width = Math.max(this.container.clientWidth, 320);
    this.renderer.setSize(width, HEIGHT);
    this.camera.aspect = width / HEIGHT;
    this.camera.updateProjectionMatrix();
  }

  clear() {
    for (const child of [...this.content.children]) this.content.remove(child);
  }

  render() {
    if (this.beforeRender) this.beforeRender();
    this.renderer.render(this.scene, this.camera);
  }

  // Look at `box` (a THREE.Box3) from the front left, above, so all of it is in view.
  frame(box) {
    const centre = box.getCenter(new THREE.Vector3());
    const radius = Math.max(box.getSize(new THREE.Vector3()).length() / 2, 0.4);
    const distance = (radius / Math.sin((this.camera.fov * Math.PI) / 360)) * 0.9;
    const direction = new THREE.Vector3(1.0, -1.35, 0.95).normalize();
    this.camera.position.copy(centre).addScaledVector(direction, distance);
    this.controls.target.copy(centre);
    this.controls.update();
  }

  // The canvas rectangle (CSS pixels: x0, y0, x1, y1) that `objects` cover, or null.
  screenBox(objects) {
    this.scene.updateMatrixWorld(true);
    const box = new THREE.Box3();
    for (const object of objects) box.expandByObject(object);
    if (box.isEmpty()) return null;
    const width = this.renderer.domElement.clientWidth;
    const height = this.renderer.domElement.clientHeight;
    let x0 = Infinity, y0 = Infinity, x1 = -Infinity, y1 = -Infinity;
    for (let i = 0; i < 8; i += 1) {
      const corner = new THREE.Vector3(
        i & 1 ? box.max.x : box.min.x, i & 2 ? box.max.y : box.min.y, i & 4 ? box.max.z : box.min.z,
      ).project(this.camera);
      const x = ((corner.x + 1) / 2) * width;
      const y = ((1 - corner.y) / 2) * height;
      x0 = Math.min(x0, x); y0 = Math.min(y0, y); x1 = Math.max(x1, x); y1 = Math.max(y1, y);
    }
    const clamp = (v, hi) => Math.round(Math.min(Math.max(v, 0), hi));
    return [clamp(x0, width), clamp(y0, height), clamp(x1, width), clamp(y1, height)];
  }
}

export { THREE };
