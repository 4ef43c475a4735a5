// The dashboard's 3D view: a robot with its collision geometry, the scene version a path was
// stored or validated in, and the path animated (play, pause, a scrubber) with the end
// effector's swept path drawn. A plan event with rejected candidates opens at the first
// failing sample of one, the link and the object (or the two links) at fault in magenta. A
// goal given as a pose is drawn as a frame marker, a Cartesian path's lines as a polyline.
//
// Everything drawn comes from the service, render-ready: the model's collision elements
// (/v1/view/models/{id}, meshes as STL of the triangles the validator checks), the scene and
// the world pose of every posed link at every frame (/v1/view/trajectories/{id},
// /v1/view/plan-events/{id}, /v1/view/cartesian-paths/{id}), computed with the service's own
// kinematics. No URDF loader and no kinematics here. The dashboard asks for a view by setting
// `data-show` on #view3d to "trajectory:ID", "event:ID" or "cartesian:ID"; once a view is fetched, #view3d reports the trajectory it shows
// (`data-trajectory`, and a "view3d-shown" event whose detail names it: for an event, its
// trajectory or the rejected candidate at fault), so the rest of the page can follow it.
import { COLORS, Stage, THREE, frameMarker, materials, polyline, primitive, setPose, stlGeometry, triangles } from "./view3d_stage.js";

const KEY_STORAGE = "trajcache.adminKey";
const ROUTES = { trajectory: "trajectories", event: "plan-events", cartesian: "cartesian-paths" };
const FRAMES_PER_SECOND = 30;
const $ = (id) => document.getElementById(id);

async function fetchApi(path, binary) {
  const headers = { Accept: binary ? "*/*" : "application/json" };
  const key = sessionStorage.getItem(KEY_STORAGE);
  if (key) headers.Authorization = `Bearer ${key}`;
  const reply = await fetch(path, { headers, cache: "no-store" });
  if (!reply.ok) {
    const body = await reply.json().catch(() => ({}));
    throw new Error(`${reply.status} ${body.detail || reply.statusText}`);
  }
  return binary ? reply.arrayBuffer() : reply.json();
}

const baseId = (name) => String(name).split("#")[0];

function describe(rejection) {
  const pairs = rejection.pairs.map((p) => `link '${p.link}' ${p.kind === "self" ? "hits link" : "hits object"} '${p.other}'`);
  const what = pairs.length ? pairs.join("; ") : rejection.joints.length ? `${rejection.joints.join(", ")} out of limits` : rejection.reason;
  const where = rejection.sample === null ? "" : ` at sample ${rejection.sample}${rejection.at ? ` (+${rejection.at.toFixed(2)})` : ""} of ${rejection.samples}, segment ${rejection.segment}`;
  return `candidate #${rejection.trajectory_id} rejected (${rejection.status.replace(/_/g, " ")}): ${what}${where}`;
}

class View3D {
  constructor(root) {
    this.root = root;
    this.models = new Map(); // model id → {view, geometries by element index}
    this.meshes = new Map(); // STL path → geometry promise
    this.materials = materials();
    this.stage = null;
    this.shown = null; // what `data-show` asked for last
    this.loading = 0;
    this.view = null;
    this.frame = 0;
    this.playing = false;
    this.links = []; // THREE.Group per posed link, in frames.links order
    $("view3d-play").addEventListener("click", () => (this.playing ? this.pause() : this.play()));
    $("view3d-scrub").addEventListener("input", (ev) => { this.pause(); this.setFrame(Number(ev.target.value)); });
    $("view3d-failure").addEventListener("click", () => { this.pause(); this.showFailure(); });
    $("view3d-candidate").addEventListener("change", (ev) => this.pick(ev.target.value));
    $("view3d-canvas").addEventListener("keydown", (ev) => this.key(ev));
    new MutationObserver(() => this.follow()).observe(root, { attributes: true, attributeFilter: ["data-show"] });
    this.follow(); // dashboard.js may have asked before this module loaded (`#event=N`)
  }

  follow() {
    const show = this.root.dataset.show;
    if (!show || show === this.shown) return;
    this.shown = show;
    const [kind, id] = show.split(":");
    this.open(kind, Number(id)).catch((err) => this.fail(String(err.message || err)));
  }

  fail(message) {
    this.root.dataset.state = "error";
    $("view3d-info").textContent = message;
    this.report(null);
  }

  // Tell the page which trajectory is shown (null: none).
  report(trajectory) {
    this.root.dataset.trajectory = trajectory === null ? "" : String(trajectory);
    this.root.dispatchEvent(new CustomEvent("view3d-shown", { detail: { trajectory } }));
  }

  ensureStage() {
    if (this.stage) return true;
    try {
      this.stage = new Stage($("view3d-canvas"));
      this.stage.beforeRender = () => this.fadeOccluders();
      return true;
    } catch (err) {
      this.fail(`No 3D view: WebGL is not available in this browser (${err.message || err})`);
      return false;
    }
  }

  // Show a trajectory or a plan event; `context`: the plan event a trajectory is shown for.
  async open(kind, id, query = "", context = null) {
    const ticket = ++this.loading;
    this.pause();
    this.root.dataset.state = "loading";
    $("view3d-info").textContent = `Loading ${kind} ${id}…`;
    const view = await fetchApi(`/v1/view/${ROUTES[kind]}/${id}${query}`);
    if (ticket !== this.loading) return; // a newer request took over
    const event = context || view.event;
    const shown = kind === "trajectory" ? id : view.failure ? view.failure.rejection.trajectory_id : event ? event.trajectory_id : null;
    this.report(shown); // even where WebGL is missing, the page follows the selection
    if (!this.ensureStage()) return;
    const model = await this.model(view.model_id);
    if (ticket !== this.loading) return;
    this.context = event;
    this.build(view, model);
    this.title(kind, id, view, shown);
    if (view.failure) this.showFailure();
    else this.setFrame(0);
    this.root.dataset.loaded = `${kind}:${id}`;
    this.root.dataset.state = "ready";
  }

  async model(modelId) {
    if (!this.models.has(modelId)) {
      const promise = (async () => {
        const view = await fetchApi(`/v1/view/models/${encodeURIComponent(modelId)}`);
        const geometries = await Promise.all(view.elements.map((e) => this.geometry(e)));
        return { view, geometries };
      })();
      this.models.set(modelId, promise);
      promise.catch(() => this.models.delete(modelId));
    }
    return this.models.get(modelId);
  }

  geometry(element) {
    if (element.kind !== "mesh") return Promise.resolve(primitive(element.kind, element.size));
    if (!this.meshes.has(element.mesh)) this.meshes.set(element.mesh, fetchApi(element.mesh, true).then(stlGeometry));
    return this.meshes.get(element.mesh);
  }

  build(view, model) {
    const stage = this.stage;
    stage.clear();
    this.view = view;
    const names = model.view.link_names;
    const posed = new Map(view.frames.links.map((link, j) => [link, j]));
    this.links = view.frames.links.map((link) => {
      const group = new THREE.Group();
      group.userData.name = names[link];
      stage.content.add(group);
      return group;
    });
    model.view.elements.forEach((element, k) => {
      const j = posed.get(element.link);
      if (j === undefined || !model.geometries[k]) return;
      this.add(this.links[j], model.geometries[k], element.origin, names[element.link], this.materials.robot);
    });
    this.robotMeshes = this.links.flatMap((g) => g.children);
    this.sceneObjects(view, names, posed);
    this.paths(view, model.view, posed);
    this.goals(view);
    const scrub = $("view3d-scrub");
    scrub.max = String(view.frames.count - 1);
    this.highlight(view.failure ? view.failure.rejection.pairs.flatMap((p) => [p.link, p.other]) : []);
    stage.frame(this.extent());
    this.root.dataset.frames = String(view.frames.count);
  }

  add(parent, geometry, pose, name, material) {
    const mesh = new THREE.Mesh(geometry, material);
    setPose(mesh, pose);
    mesh.userData.name = name;
    mesh.userData.material = material;
    parent.add(mesh);
    return mesh;
  }

  sceneObjects(view, names, posed) {
    const scene = view.scene;
    this.objectMeshes = [];
    if (!scene) return;
    const shape = (o) => (o.type === "mesh" ? triangles(o.vertices, o.faces) : primitive(o.type, o.size));
    const pose = (o) => [...o.pose.position, ...o.pose.orientation];
    for (const o of scene.objects) {
      const geometry = shape(o);
      if (geometry) this.objectMeshes.push(this.add(this.stage.content, geometry, pose(o), o.id, this.materials.scene));
    }
    for (const a of scene.attached_objects || []) { // carried by a link: drawn as part of the robot
      const j = posed.get(names.indexOf(a.link));
      const geometry = shape(a.object);
      if (j !== undefined && geometry) this.robotMeshes.push(this.add(this.links[j], geometry, pose(a.object), a.object.id, this.materials.robot));
    }
  }

  // The end effector's swept path (and a planar base's), through every frame.
  paths(view, model, posed) {
    const frames = view.frames;
    const trace = (j) => frames.poses.map((p) => new THREE.Vector3(p[7 * j], p[7 * j + 1], p[7 * j + 2]));
    const ee = posed.get(model.end_effector_link);
    if (ee !== undefined && frames.count > 1) {
      const line = new THREE.Line(new THREE.BufferGeometry().setFromPoints(trace(ee)), this.materials.path);
      this.stage.content.add(line);
      this.marker = new THREE.Mesh(new THREE.SphereGeometry(0.018, 16, 12), this.materials.path);
      this.stage.content.add(this.marker);
      this.eeIndex = ee;
    } else this.marker = null;
    const base = posed.get(0);
    if (model.base === "planar" && base !== undefined && frames.count > 1) {
      const points = trace(base).map((v) => new THREE.Vector3(v.x, v.y, 0.005));
      const line = new THREE.Line(new THREE.BufferGeometry().setFromPoints(points), this.materials.base);
      line.computeLineDistances();
      this.stage.content.add(line);
    }
  }

  // The goal pose as a frame marker; a Cartesian path's lines through its waypoints.
  goals(view) {
    const goal = view.goal_pose;
    if (goal) this.stage.content.add(frameMarker(goal.position, goal.orientation));
    const lines = view.cartesian;
    if (lines) this.stage.content.add(polyline(lines.poses, COLORS.lines));
    this.root.dataset.goal = goal ? goal.position.map((v) => v.toFixed(3)).join(",") : "";
    this.root.dataset.waypoints = lines ? String(lines.poses.length - 1) : "";
  }

  // What to look at: the robot over the whole path, with some of the scene around it.
  extent() {
    const box = new THREE.Box3();
    const frames = this.view.frames;
    for (let j = 0; j < this.links.length; j += 1) {
      for (const p of frames.poses) box.expandByPoint(new THREE.Vector3(p[7 * j], p[7 * j + 1], p[7 * j + 2]));
    }
    box.expandByScalar(0.2);
    box.min.z = Math.min(box.min.z, 0);
    return box;
  }

  // Scene objects between the camera and the robot (a room's near wall, a stall partition)
  // are drawn faint, so the robot is seen wherever it stands; the rest keeps its shade.
  fadeOccluders() {
    if (!this.objectMeshes || !this.objectMeshes.length || !this.robotMeshes.length) return;
    const robot = new THREE.Box3();
    for (const mesh of this.robotMeshes) robot.expandByObject(mesh);
    const eye = this.stage.camera.position;
    const centre = robot.getCenter(new THREE.Vector3());
    const targets = [centre, new THREE.Vector3(centre.x, centre.y, robot.max.z)];
    for (const mesh of this.objectMeshes) {
      if (mesh.material === this.materials.highlight) continue;
      if (!mesh.userData.box) mesh.userData.box = new THREE.Box3().setFromObject(mesh);
      const box = mesh.userData.box;
      const hides = !box.containsPoint(eye) && targets.some((target) => {
        const ray = new THREE.Ray(eye.clone(), target.clone().sub(eye).normalize());
        const hit = ray.intersectBox(box, new THREE.Vector3());
        return hit !== null && hit.distanceTo(eye) < target.distanceTo(eye) && !box.containsPoint(target);
      });
      mesh.material = hides ? this.materials.faded : mesh.userData.material;
    }
  }

  highlight(names) {
    const wanted = new Set(names.map(String));
    const hit = (m) => wanted.has(m.userData.name) || wanted.has(baseId(m.userData.name));
    const marked = [];
    for (const mesh of [...this.robotMeshes, ...this.objectMeshes]) {
      const on = hit(mesh);
      mesh.material = on ? this.materials.highlight : mesh.userData.material;
      mesh.renderOrder = on ? 2 : 0;
      if (on) marked.push(mesh.userData.name);
    }
    this.root.dataset.highlighted = [...new Set(marked)].sort().join(",");
  }

  pose(values) {
    this.links.forEach((group, j) => setPose(group, values, 7 * j));
    if (this.marker) this.marker.position.set(values[7 * this.eeIndex], values[7 * this.eeIndex + 1], values[7 * this.eeIndex + 2]);
    this.stage.render();
    const box = this.stage.screenBox(this.robotMeshes);
    this.root.dataset.robotBox = box ? box.join(",") : "";
  }

  setFrame(k) {
    const frames = this.view.frames;
    this.frame = Math.max(0, Math.min(frames.count - 1, Math.round(k)));
    $("view3d-scrub").value = String(this.frame);
    this.root.dataset.frame = String(this.frame);
    this.root.dataset.failure = "";
    this.pose(frames.poses[this.frame]);
    const sample = frames.sample[this.frame];
    const thinned = frames.count < frames.samples ? ` (frame ${this.frame + 1} of ${frames.count})` : "";
    $("view3d-frame").textContent = `sample ${sample} of ${frames.samples}${thinned}`;
  }

  showFailure() {
    const failure = this.view && this.view.failure;
    if (!failure) return;
    this.setFrame(failure.frame);
    this.pose(failure.poses); // the failing state itself, which may lie between two frames
    this.root.dataset.failure = "shown";
    $("view3d-frame").textContent += " · at the failure";
  }

  play() {
    if (!this.view || this.view.frames.count < 2) return;
    if (this.frame >= this.view.frames.count - 1) this.setFrame(0);
    this.playing = true;
    $("view3d-play").textContent = "Pause";
    let last = performance.now();
    let position = this.frame;
    const step = (now) => {
      if (!this.playing) return;
      position += ((now - last) / 1000) * FRAMES_PER_SECOND;
      last = now;
      this.setFrame(position);
      if (this.frame >= this.view.frames.count - 1) this.pause();
      else requestAnimationFrame(step);
    };
    requestAnimationFrame(step);
  }

  // Space plays or pauses; arrows step a frame (ten with Shift); Home and End jump.
  key(ev) {
    if (!this.view) return;
    const step = ev.shiftKey ? 10 : 1;
    const moves = { ArrowLeft: this.frame - step, ArrowRight: this.frame + step, Home: 0, End: this.view.frames.count - 1 };
    if (ev.key === " ") this.playing ? this.pause() : this.play();
    else if (ev.key in moves) { this.pause(); this.setFrame(moves[ev.key]); }
    else return;
    ev.preventDefault();
  }

  pause() {
    this.playing = false;
    $("view3d-play").textContent = "Play";
  }

  title(kind, id, view, shown) {
    const event = this.context;
    const select = $("view3d-candidate");
    select.textContent = "";
    if (event && event.trajectory_id !== null) select.add(new Option(`${event.source === "cache" ? "served" : "stored"} trajectory #${event.trajectory_id}`, "trajectory"));
    (event ? event.rejections : []).forEach((r, k) => select.add(new Option(`rejected #${r.trajectory_id} (${r.status.replace(/_/g, " ")})`, String(k))));
    select.hidden = select.options.length < 2;
    select.value = view.failure ? String(view.failure.candidate) : "trajectory";
    $("view3d-failure").hidden = !view.failure;
    const of = event ? `plan event #${event.event_id} of ${event.robot_id} (${event.status})` : "";
    const trajectory = `${view.failure ? "rejected candidate" : "trajectory"} #${shown}`;
    const what = kind === "event" ? `${of} · ${trajectory}`
      : kind === "cartesian" ? `Cartesian path #${id} of ${view.cartesian.link}`
      : `trajectory #${id}${of ? ` for ${of}` : ""}`;
    $("view3d-title").textContent = `${what} · ${sceneLabel(view)}`;
    const lines = view.failure ? [describe(view.failure.rejection)] : [`${view.key_states.length} key states, ${view.frames.samples} validation samples`];
    $("view3d-info").textContent = [...lines, ...view.notes].join(" · ");
  }

  pick(value) {
    const event = this.context;
    if (!event) return;
    const opened = value === "trajectory"
      ? this.open("trajectory", event.trajectory_id, event.scene_hash ? `?scene_hash=${event.scene_hash}` : "", event)
      : this.open("event", event.event_id, `?candidate=${value}`);
    opened.catch((err) => this.fail(String(err.message || err)));
  }
}

// Where the drawn scene comes from: a robot's version, a seed job's scene, or only its hash.
function sceneLabel(view) {
  const scene = view.scene;
  const hash = view.scene_hash ? view.scene_hash.slice(0, 10) : "none";
  if (scene && scene.robot_id !== null) return `scene v${scene.version} of ${scene.robot_id}`;
  if (scene && scene.seed_job_id !== null) return `scene of seed job #${scene.seed_job_id}`;
  return `scene ${hash}`;
}

const root = document.getElementById("view3d");
if (root) window.trajcacheView3D = new View3D(root);
