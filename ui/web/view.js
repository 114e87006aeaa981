// mrroc operator console: the live 3D view. Every robot of the set is drawn from its own URDF
// (GET /api/robots/<robot>/urdf) at its base in the cell, moving with its measured joints
// (GET /api/joints, polled every 20 ms: the EDPs send a robot state every 20 ms); the pose it is
// commanded to is drawn as a translucent ghost while it differs from the measured one. Links
// without visual geometry in their URDF (the conveyor's belt) are drawn from the boxes,
// cylinders, spheres and capsules of the robot's MJCF (GET /api/robots/<robot>/mjcf).
// three.js and urdf-loader come from the console itself (/vendor/, the import map of index.html;
// `npm ci --prefix ui/vendor` installs them): nothing is fetched from elsewhere.
// The cell emulator's scene objects (a set with [emulator] scene: the table, the bar, parts on the
// conveyor) are drawn with three.js' boxes, spheres, cylinders and capsules (GET /api/objects)
// at the poses the emulator publishes (with every GET /api/joints).
// For tests: window.mrrocView (jointValues, linkPoses, objects, stats, visiblePixels).
// docs/operating.md.

const POLL_PERIOD_MS = 20;
const GHOST_MIN_RAD = 1e-3;  // the ghost shows when a commanded joint is this far from the measured
const LINK_COLOURS = [0xd9822b, 0x4f5b66];  // alternate links: orange, slate
const GHOST_COLOUR = 0x2f81f7;
const GHOST_SHRINK = 0.97;

const params = new URLSearchParams(window.location.search);
const token = params.get("token") || sessionStorage.getItem("mrroc-token") || "";
const panel = document.getElementById("view");
const note = document.getElementById("view-note");

function say(text, bad) {
  note.textContent = text;
  note.className = bad ? "note error" : "note";
}

async function get(path, as) {
  const headers = token ? { Authorization: "Bearer " + token } : {};
  const response = await fetch(path, { headers });
  if (!response.ok)
    throw new Error(`GET ${path}: HTTP ${response.status}: ${await response.text()}`);
  return as === "text" ? response.text() : response.json();
}

let THREE, OrbitControls, URDFLoader;
try {
  THREE = await import("three");
  ({ OrbitControls } = await import("three/examples/jsm/controls/OrbitControls.js"));
  URDFLoader = (await import("urdf-loader")).default;
} catch (e) {
  say("3D view unavailable: the console does not serve three.js and urdf-loader (install them " +
      "with `npm ci --prefix ui/vendor` in the source tree and build mrroc-ui again): " + e, true);
  throw e;
}

// --- the scene: z up, as the URDFs and the cell ----------------------------------------------
THREE.Object3D.DEFAULT_UP.set(0, 0, 1);
const scene = new THREE.Scene();
scene.background = new THREE.Color(0xeef1f5);
const camera = new THREE.PerspectiveCamera(40, 16 / 9, 0.02, 100);
camera.position.set(2.2, -3.0, 1.8);
/// The renderer's name when WebGL runs on the CPU (SwiftShader, llvmpipe: a browser without a GPU,
/// e.g. headless), else "": there the view draws without antialiasing, three times faster.
function softwareRenderer() {
  try {
    const gl = document.createElement("canvas").getContext("webgl2");
    const info = gl && gl.getExtension("WEBGL_debug_renderer_info");
    const name = info ? String(gl.getParameter(info.UNMASKED_RENDERER_WEBGL)) : "";
    gl?.getExtension("WEBGL_lose_context")?.loseContext();
    return /swiftshader|llvmpipe|softpipe/i.test(name) ? name : "";
  } catch (e) {
    return "";
  }
}
const software = softwareRenderer();
let renderer;
try {
  renderer = new THREE.WebGLRenderer({ antialias: !software });
} catch (e) {
  say("3D view unavailable: this browser gives the page no WebGL: " + e, true);
  throw e;
}
// A CPU renderer draws every pixel in software: at most one pixel per CSS pixel there.
renderer.setPixelRatio(software ? Math.min(1, window.devicePixelRatio || 1)
                                : window.devicePixelRatio || 1);
panel.appendChild(renderer.domElement);
const controls = new OrbitControls(camera, renderer.domElement);
controls.target.set(0, 0, 0.6);
controls.update();
// Drawn when something changed (a robot state, the camera, the size): nothing is drawn at rest.
let dirty = true;
controls.addEventListener("change", () => { dirty = true; });

scene.add(new THREE.HemisphereLight(0xffffff, 0x8d8d8d, 2.2));
const sun = new THREE.DirectionalLight(0xffffff, 2.4);
sun.position.set(3, -4, 6);
scene.add(sun);
const fill = new THREE.DirectionalLight(0xffffff, 0.8);
fill.position.set(-4, 3, 2);
scene.add(fill);
let grid = null;
const axes = new THREE.AxesHelper(0.3);
scene.add(axes);

function makeGrid(half) {
  if (grid) scene.remove(grid);
  const size = 2 * Math.max(2, Math.ceil(half));
  grid = new THREE.GridHelper(size, size * 4, 0x8c959f, 0xc9d1d9);
  grid.rotation.x = Math.PI / 2;  // the x-y plane (the floor)
  scene.add(grid);
}
makeGrid(2);

function resize() {
  const width = Math.max(200, panel.clientWidth);
  const height = Math.round(Math.min(520, Math.max(260, width * 0.56)));
  renderer.setSize(width, height);
  camera.aspect = width / height;
  camera.updateProjectionMatrix();
  dirty = true;
}
new ResizeObserver(resize).observe(panel);
resize();

// --- robots -------------------------------------------------------------------------------------
// name -> {name, jointNames, group, model, ghost, step, utime, q, qDesired, applied}
const robots = new Map();

function styleModel(model, ghost) {
  let index = 0;
  for (const link of Object.values(model.links)) {
    const colour = ghost ? GHOST_COLOUR : LINK_COLOURS[index++ % LINK_COLOURS.length];
    link.traverse((object) => {
      if (!object.isMesh) return;
      // A colour the URDF or MJCF gives stays (not on the ghost).
      const own = object.userData.mrrocColour;
      // The ghost's shapes a little smaller, about their centres: where it coincides with the
      // robot it stays inside it, so only the parts ahead of the robot show.
      if (ghost) object.scale.multiplyScalar(GHOST_SHRINK);
      // On a CPU renderer, lighting per vertex (Lambert) instead of per pixel (Phong): about
      // half the cost of a frame, so the view keeps up with the robot states.
      const Material = software ? THREE.MeshLambertMaterial : THREE.MeshPhongMaterial;
      object.material = new Material({
        color: ghost ? colour : (own ?? colour),
        ...(software ? {} : { shininess: 40 }),
        transparent: ghost,
        opacity: ghost ? 0.3 : 1,
        depthWrite: !ghost,
        // Where the ghost coincides with the robot (the joints commanded as measured), the
        // robot's surface wins the depth test: no flicker.
        polygonOffset: ghost,
        polygonOffsetFactor: ghost ? 1 : 0,
        polygonOffsetUnits: ghost ? 4 : 0,
      });
    });
  }
}

function quaternionFromRotationVector(r) {
  const angle = Math.hypot(r[0], r[1], r[2]);
  const q = new THREE.Quaternion();
  if (angle > 1e-12)
    q.setFromAxisAngle(new THREE.Vector3(r[0] / angle, r[1] / angle, r[2] / angle), angle);
  return q;
}

// MJCF geometry for the links whose URDF has none ---------------------------------------------
function numbers(text, fallback) {
  if (!text) return fallback;
  return text.trim().split(/\s+/).map(Number);
}

/// A MuJoCo geom's shape from its type and size [m] (box: half-sizes; sphere: radius; cylinder,
/// capsule: radius, half-length along z), centred at its frame; null for other types.
function shapeGeometry(type, size) {
  let geometry;
  if (type === "box") geometry = new THREE.BoxGeometry(2 * size[0], 2 * size[1], 2 * size[2]);
  else if (type === "sphere") geometry = new THREE.SphereGeometry(size[0], 24, 16);
  else if (type === "cylinder" || type === "capsule") {
    geometry = type === "cylinder"
      ? new THREE.CylinderGeometry(size[0], size[0], 2 * size[1], software ? 16 : 32)
      : new THREE.CapsuleGeometry(size[0], 2 * size[1], software ? 4 : 8, software ? 12 : 24);
    geometry.rotateX(Math.PI / 2);  // MJCF's cylinders run along z, three.js' along y
  } else return null;  // planes, meshes, height fields: not drawn
  return geometry;
}

function mjcfGeom(element) {
  const type = element.getAttribute("type") || "sphere";
  const size = numbers(element.getAttribute("size"), [0.01, 0.01, 0.01]);
  const geometry = shapeGeometry(type, size);
  if (!geometry) return null;
  const mesh = new THREE.Mesh(geometry);
  const pos = numbers(element.getAttribute("pos"), [0, 0, 0]);
  mesh.position.set(pos[0], pos[1], pos[2]);
  const quat = numbers(element.getAttribute("quat"), null);  // w x y z
  if (quat) mesh.quaternion.set(quat[1], quat[2], quat[3], quat[0]).normalize();
  const rgba = numbers(element.getAttribute("rgba"), null);
  if (rgba)
    mesh.userData.mrrocColour = new THREE.Color().setRGB(rgba[0], rgba[1], rgba[2],
                                                         THREE.SRGBColorSpace);
  return mesh;
}

function hasVisual(link) {
  let found = false;
  link.traverse((o) => { if (o.isMesh) found = true; });
  return found;
}

/// Adds the MJCF's geoms of each body named as a link without visuals (the worldbody's own
/// geoms to the root link), at the body's frame: the URDF and MJCF of a robot name their
/// links and bodies alike.
function addMjcfGeometry(model, text) {
  const doc = new DOMParser().parseFromString(text, "application/xml");
  const world = doc.querySelector("worldbody");
  if (!world) return 0;
  let added = 0;
  const links = Object.values(model.links);
  const root = links.find((l) => !l.parent || !l.parent.isURDFJoint) || links[0];
  const add = (link, body) => {
    for (const child of body.children)
      if (child.tagName === "geom" && child.getAttribute("group") !== "3") {
        const mesh = mjcfGeom(child);
        if (mesh) { link.add(mesh); ++added; }
      }
  };
  if (root && !hasVisual(root)) add(root, world);
  for (const body of world.querySelectorAll("body")) {
    const link = model.links[body.getAttribute("name")];
    if (link && link !== root && !hasVisual(link)) add(link, body);
  }
  return added;
}

async function loadRobot(info) {
  const urdf = await get(`/api/robots/${info.name}/urdf`, "text");
  const loader = new URDFLoader();
  loader.parseCollision = false;
  const parse = () => {
    const m = loader.parse(urdf);
    // Draw what is measured, also beyond a limit.
    for (const joint of Object.values(m.joints)) joint.ignoreLimits = true;
    return m;
  };
  const model = parse();
  const ghost = parse();
  if (Object.values(model.links).some((l) => !hasVisual(l))) {
    try {
      const mjcf = await get(`/api/robots/${info.name}/mjcf`, "text");
      addMjcfGeometry(model, mjcf);
      addMjcfGeometry(ghost, mjcf);
    } catch (e) { /* drawn from its URDF alone */ }
  }
  styleModel(model, false);
  styleModel(ghost, true);
  ghost.visible = false;
  const group = new THREE.Group();
  group.name = info.name;
  const base = info.base || [0, 0, 0, 0, 0, 0];
  group.position.set(base[0], base[1], base[2]);
  group.quaternion.copy(quaternionFromRotationVector(base.slice(3)));
  group.add(model);
  group.add(ghost);
  scene.add(group);
  robots.set(info.name, {
    name: info.name, jointNames: info.joint_names, group, model, ghost,
    step: null, utime: null, q: null, qDesired: null, applied: [],
  });
}

// --- the scene's objects ------------------------------------------------------------------------
// The cell emulator's objects (a set with [emulator] scene): GET /api/objects gives their shapes,
// sizes, colours and what they are attached to; /api/joints carries their poses with every poll
// (the emulator sends them about 30 times a second). An object attached to a link of a drawn
// robot ("conveyor/belt_link") is drawn on that link at its pose there, so it moves with the
// drawn robot; every other object (free bodies, ones fixed to the world) at the emulator's pose.
// [{name, shape, size, attach, mesh, link}] in the order of /api/objects and of the poses.
let objects = [];
let objectsCount = 0;       // objects the console listed (those drawn are in `objects`)
let objectsSeq = null;      // the emulator's number of the poses drawn
let objectsUtime = null;
let objectsLoading = false;
let objectsRetry = 0;       // performance.now() before which no new GET /api/objects is made
const objectGroup = new THREE.Group();
objectGroup.name = "scene objects";
scene.add(objectGroup);

function objectMaterial(rgba) {
  const Material = software ? THREE.MeshLambertMaterial : THREE.MeshPhongMaterial;
  return new Material({
    color: new THREE.Color().setRGB(rgba[0], rgba[1], rgba[2], THREE.SRGBColorSpace),
    ...(software ? {} : { shininess: 30 }),
    transparent: rgba[3] < 1,
    opacity: rgba[3],
  });
}

/// The drawn link an object is attached to ("<robot>/<link>" of a robot of the view), or null.
function attachLink(attach) {
  const slash = attach.indexOf("/");
  if (slash < 0) return null;
  const r = robots.get(attach.slice(0, slash));
  return (r && r.model.links[attach.slice(slash + 1)]) || null;
}

function clearObjects() {
  for (const o of objects) {
    o.mesh.removeFromParent();
    o.mesh.geometry.dispose();
    o.mesh.material.dispose();
  }
  objects = [];
  objectsCount = 0;
  objectsSeq = null;
}

async function loadObjects() {
  if (objectsLoading || performance.now() < objectsRetry) return;
  objectsLoading = true;
  try {
    const data = await get("/api/objects");
    clearObjects();
    for (const [index, info] of data.objects.entries()) {
      const geometry = shapeGeometry(info.shape, info.size);
      if (!geometry) continue;
      const mesh = new THREE.Mesh(geometry, objectMaterial(info.rgba));
      mesh.name = info.name;
      const link = attachLink(info.attach);
      const [x, y, z] = link ? info.local_position : info.position;
      const [w, qx, qy, qz] = link ? info.local_quaternion : info.quaternion;
      mesh.position.set(x, y, z);
      mesh.quaternion.set(qx, qy, qz, w).normalize();
      (link || objectGroup).add(mesh);
      objects.push({ name: info.name, shape: info.shape, size: info.size, attach: info.attach,
                     mesh, link, index });
    }
    // Shapes it cannot draw would make every poll ask again: once a second at most then.
    if (objects.length !== data.objects.length) objectsRetry = performance.now() + 1000;
    objectsCount = data.objects.length;
    objectsSeq = data.seq;
    objectsUtime = data.utime;
    framedBox = null;  // frame the objects too
    dirty = true;
  } catch (e) {
    objectsRetry = performance.now() + 1000;  // the console is away: try again in a second
  } finally {
    objectsLoading = false;
  }
}

/// The poses of one /api/joints answer ({seq, utime, poses: [[x, y, z, qw, qx, qy, qz], ...]}).
function applyObjectPoses(data) {
  if (!data) return;
  if (data.poses.length !== objectsCount) {  // other objects (the emulator started again)
    loadObjects();
    return;
  }
  if (data.seq === objectsSeq) return;
  objectsSeq = data.seq;
  objectsUtime = data.utime;
  for (const o of objects) {
    if (o.link) continue;  // drawn with its link
    const p = data.poses[o.index];
    if (o.mesh.position.x !== p[0] || o.mesh.position.y !== p[1] || o.mesh.position.z !== p[2] ||
        o.mesh.quaternion.w !== p[3] || o.mesh.quaternion.x !== p[4] ||
        o.mesh.quaternion.y !== p[5] || o.mesh.quaternion.z !== p[6]) {
      o.mesh.position.set(p[0], p[1], p[2]);
      o.mesh.quaternion.set(p[4], p[5], p[6], p[3]);
      dirty = true;
    }
  }
}

/// Sets the joints; true when one of them changed (else nothing needs to be drawn again).
function setJoints(model, names, values) {
  let changed = false;
  names.forEach((name, i) => {
    const joint = model.joints[name];
    if (joint && typeof values[i] === "number" && joint.setJointValue(values[i])) changed = true;
  });
  return changed;
}

// --- updates and drawing -----------------------------------------------------------------------
const frames = [];  // times of the frames drawn in the last 2 s [ms]
let polls = 0;

function recent(times, now) {
  while (times.length && times[0] < now - 2000) times.shift();
}

/// The box that every robot has filled since the page loaded: the camera frames it (and widens
/// as a robot reaches further) until the operator moves the camera.
let framedBox = null;
let cameraMoved = false;
let lastFrameCheck = -Infinity;
controls.addEventListener("start", () => { cameraMoved = true; });

function frameCamera() {
  scene.updateMatrixWorld(true);
  const box = new THREE.Box3();
  for (const r of robots.values()) box.expandByObject(r.model);
  box.expandByObject(objectGroup);
  if (box.isEmpty()) return;
  box.expandByPoint(new THREE.Vector3(0, 0, 0));
  if (framedBox && framedBox.containsBox(box)) return;
  framedBox = framedBox ? framedBox.union(box) : box;
  const centre = framedBox.getCenter(new THREE.Vector3());
  const radius = Math.max(0.5, framedBox.getSize(new THREE.Vector3()).length() / 2);
  const distance = radius / Math.sin(THREE.MathUtils.degToRad(camera.fov / 2)) * 0.9;
  const direction = new THREE.Vector3(0.62, -0.85, 0.45).normalize();
  controls.target.copy(centre);
  camera.position.copy(centre).addScaledVector(direction, distance);
  camera.near = distance / 100;
  camera.far = distance * 20;
  camera.updateProjectionMatrix();
  controls.update();
  dirty = true;
  makeGrid(Math.max(Math.abs(framedBox.min.x), Math.abs(framedBox.max.x),
                    Math.abs(framedBox.min.y), Math.abs(framedBox.max.y)) + 0.5);
}

let inFlight = 0;
let lastSent = 0;     // number of the last request sent
let lastApplied = 0;  // number of the request whose answer was applied last

/// One GET /api/joints every POLL_PERIOD_MS, at most two under way (an answer's latency does not
/// lower the rate); an answer older than one already applied is dropped.
async function pollJoints() {
  if (inFlight >= 2) return;
  const number = ++lastSent;
  ++inFlight;
  let data;
  try {
    data = await get("/api/joints");
  } catch (e) {
    return;  // the console is away: the page's badge says so; the next poll tries again
  } finally {
    --inFlight;
  }
  if (number < lastApplied) return;
  lastApplied = number;
  ++polls;
  for (const state of data.robots) {
    const r = robots.get(state.name);
    if (!r || state.step === null || state.step === r.step) continue;
    const desired = state.q_desired && state.q_desired.length === state.q.length
      ? state.q_desired : state.q;
    const ghostVisible = desired.some((v, i) => Math.abs(v - state.q[i]) > GHOST_MIN_RAD);
    if (setJoints(r.model, r.jointNames, state.q) | setJoints(r.ghost, r.jointNames, desired) ||
        ghostVisible !== r.ghost.visible)
      dirty = true;
    r.ghost.visible = ghostVisible;
    r.step = state.step;
    r.utime = state.utime;
    r.q = state.q;
    r.qDesired = desired;
    r.applied.push(performance.now());
  }
  applyObjectPoses(data.objects);
  const now = performance.now();
  if (!cameraMoved && now - lastFrameCheck > 250 &&
      [...robots.values()].every((r) => r.step !== null)) {
    lastFrameCheck = now;
    frameCamera();
  }
}

function draw(now) {
  if (dirty) {
    dirty = false;
    renderer.render(scene, camera);
    frames.push(now);
  }
  recent(frames, now);
  requestAnimationFrame(draw);
}

function rate(times) {
  const now = performance.now();
  recent(times, now);
  const inWindow = times.filter((t) => t >= now - 1000);
  return inWindow.length;  // per second, over the last second
}

function showStatus() {
  const parts = [...robots.values()].map((r) =>
    `${r.name}: step ${r.step ?? "–"}, ${rate(r.applied)} states/s` +
    (r.ghost.visible ? ", commanded pose shown" : ""));
  if (objects.length) parts.push(`${objects.length} scene objects`);
  say(`${parts.join("; ")}; ${rate(frames)} frames/s${software ? " (drawn on the CPU)" : ""}. ` +
      "Solid: measured joints; translucent blue: " +
      "the commanded pose. Drag to turn, wheel to zoom, right-drag to pan.");
}

// --- for tests: what is drawn ----------------------------------------------------------------
window.mrrocView = {
  ready: false,
  robots: () => [...robots.keys()],
  /// The joint values drawn (read back from the model's joints), the commanded ones of the ghost
  /// and the servo step and time of the robot state they came from.
  jointValues(name) {
    const r = robots.get(name);
    if (!r) return null;
    const read = (model) => r.jointNames.map((j) => model.joints[j] ? model.joints[j].angle : null);
    return { step: r.step, utime: r.utime, q: read(r.model), q_desired: read(r.ghost),
             ghost_visible: r.ghost.visible };
  },
  /// Each link's drawn pose in the cell: position [m] and quaternion [x, y, z, w].
  linkPoses(name, ghost = false) {
    const r = robots.get(name);
    if (!r) return null;
    scene.updateMatrixWorld(true);
    const out = { step: r.step };
    for (const [linkName, link] of Object.entries((ghost ? r.ghost : r.model).links)) {
      const p = new THREE.Vector3(), q = new THREE.Quaternion(), s = new THREE.Vector3();
      link.matrixWorld.decompose(p, q, s);
      out[linkName] = { position: p.toArray(), quaternion: q.toArray() };
    }
    return out;
  },
  /// The scene's objects as drawn: name, shape, size [m] (read back from the drawn geometry:
  /// box half-sizes, sphere radius, cylinder and capsule radius and half-length), rgba, attach,
  /// drawn_on ("link": on the drawn link of `attach`, "emulator": at the emulator's pose), and
  /// the drawn pose in the cell: position [m], quaternion [w, x, y, z]; with the seq and utime of
  /// the emulator's poses drawn.
  objects() {
    scene.updateMatrixWorld(true);
    const list = objects.map((o) => {
      const g = o.mesh.geometry.parameters;
      const size = o.shape === "box" ? [g.width / 2, g.height / 2, g.depth / 2]
        : o.shape === "sphere" ? [g.radius]
        : o.shape === "cylinder" ? [g.radiusTop, g.height / 2]
        : [g.radius, g.height / 2];  // a capsule: its cylinder part
      const p = new THREE.Vector3(), q = new THREE.Quaternion(), s = new THREE.Vector3();
      o.mesh.matrixWorld.decompose(p, q, s);
      const c = o.mesh.material.color.clone().convertLinearToSRGB();
      return { name: o.name, shape: o.shape, size, attach: o.attach,
               rgba: [c.r, c.g, c.b, o.mesh.material.opacity],
               drawn_on: o.link ? "link" : "emulator",
               position: p.toArray(), quaternion: [q.w, q.x, q.y, q.z] };
    });
    return { seq: objectsSeq, utime: objectsUtime, objects: list };
  },
  /// Rates over the last second: robot states applied per robot, frames drawn (a frame is drawn
  /// when something changed), polls done.
  stats() {
    const perRobot = {};
    for (const r of robots.values()) perRobot[r.name] = rate(r.applied);
    return { frames_per_s: rate(frames), states_per_s: perRobot, polls };
  },
  /// Draws once and counts the pixels of the canvas that are neither background nor grid:
  /// the robots' (and the axes') share of the picture; with `withObjects` false, without the
  /// scene's objects.
  visiblePixels(withObjects = true) {
    for (const o of objects) o.mesh.visible = withObjects;
    renderer.render(scene, camera);
    for (const o of objects) o.mesh.visible = true;
    dirty = true;
    const gl = renderer.getContext();
    const w = gl.drawingBufferWidth, h = gl.drawingBufferHeight;
    const pixels = new Uint8Array(w * h * 4);
    gl.readPixels(0, 0, w, h, gl.RGBA, gl.UNSIGNED_BYTE, pixels);
    let coloured = 0;
    for (let i = 0; i < pixels.length; i += 4) {
      const r = pixels[i], g = pixels[i + 1], b = pixels[i + 2];
      if (Math.max(r, g, b) - Math.min(r, g, b) > 40) ++coloured;  // saturated: not grey
    }
    return { width: w, height: h, coloured };
  },
};

// --- start -------------------------------------------------------------------------------------
say("3D view: loading the robots' models…");
for (;;) {
  try {
    const state = await get("/api/state");
    for (const info of state.robots) await loadRobot(info);
    break;
  } catch (e) {
    say("3D view: waiting for the console: " + e.message, true);
    for (const r of robots.values()) scene.remove(r.group);
    robots.clear();
    await new Promise((resolve) => setTimeout(resolve, 1000));
  }
}
window.mrrocView.ready = true;
requestAnimationFrame(draw);
setInterval(pollJoints, POLL_PERIOD_MS);
setInterval(showStatus, 500);
