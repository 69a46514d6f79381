// arm3d.js - the console's 3D view: the arm drawn from the daemon's URDF with three.js (Debian's libjs-three,
// served by rbx1d), its joints from the status on the page's event stream, the table, the places, the camera's
// view at the scan pose, the last scan's objects where the map in force puts them (GET /api/scene), and a pick's
// planned tool path (its "planned" event) before it runs. Drag to orbit, wheel to zoom, right-drag to pan.
// For tests and the curious: #arm3d's data-joints is the joint angles (degrees) last drawn, data-frames the
// number of frames rendered; window.arm3d the same and more.
'use strict';
(() => {
  const box = document.getElementById('arm3d');
  if (!box) return;
  if (!window.THREE || !THREE.OrbitControls) {
    box.textContent = 'no 3D view: three.js did not load (rbx1d serves it from Debian\'s libjs-three)';
    return;
  }
  const T = THREE;
  const m = (mm) => mm / 1000;  // the scene's millimetres to the URDF's metres
  const nums = (s) => (s || '').trim().split(/\s+/).filter(Boolean).map(Number);
  const view = { robot: null, scene: null, joints_deg: null, finger_m: null, frames: 0, path: [], objects: 0 };
  window.arm3d = view;

  // ---- three.js: Z up as in ROS (REP-103), a camera looking at the arm from the front right --------------------
  const renderer = new T.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
  renderer.setPixelRatio(window.devicePixelRatio || 1);
  box.appendChild(renderer.domElement);
  const scene = new T.Scene();
  scene.background = new T.Color(0xf3f4f6);
  const sky = new T.HemisphereLight(0xffffff, 0x8a8070, 0.9);
  sky.position.set(0, 0, 1);  // the sky above: +z
  scene.add(sky);
  const sun = new T.DirectionalLight(0xffffff, 0.6);
  sun.position.set(1, -1.5, 2);
  scene.add(sun);
  const camera = new T.PerspectiveCamera(40, 1, 0.01, 20);
  camera.up.set(0, 0, 1);
  camera.position.set(1.45, -1.35, 1.0);  // the whole arm straight up (0.82 m) and the table in view
  const controls = new T.OrbitControls(camera, renderer.domElement);
  controls.target.set(0.15, 0, 0.32);
  controls.update();
  const world = new T.Group();  // table, places, camera view, objects: rebuilt with each scene
  const path = new T.Group();   // the planned tool path
  scene.add(world, path);

  let pending = false;
  function render() {
    if (pending) return;
    pending = true;
    requestAnimationFrame(() => {
      pending = false;
      renderer.render(scene, camera);
      box.dataset.frames = ++view.frames;
      if (view.joints_deg) box.dataset.joints = JSON.stringify(view.joints_deg);  // what this frame shows
    });
  }
  controls.addEventListener('change', render);
  // Where a link's origin is drawn on the canvas (CSS pixels from its top left), for the browser test.
  view.screen = (link) => {
    const o = scene.getObjectByName(link);
    if (!o) return null;
    const p = o.getWorldPosition(new T.Vector3()).project(camera), c = renderer.domElement;
    return [(p.x + 1) / 2 * c.clientWidth, (1 - p.y) / 2 * c.clientHeight];
  };
  function resize() {
    const w = box.clientWidth || 400, h = Math.max(240, Math.round(w * 0.6));
    renderer.setSize(w, h);
    camera.aspect = w / h;
    camera.updateProjectionMatrix();
    render();
  }
  new ResizeObserver(resize).observe(box);

  // ---- the URDF: links with their box / cylinder / sphere visuals, joints as nested groups -------------------
  // An <origin>'s pose: URDF rpy is R = Rz(yaw) Ry(pitch) Rx(roll), three.js's Euler order 'ZYX'.
  function placed(origin) {
    const g = new T.Group();
    if (!origin) return g;
    const [x, y, z] = nums(origin.getAttribute('xyz') || '0 0 0');
    const [r, p, w] = nums(origin.getAttribute('rpy') || '0 0 0');
    g.position.set(x, y, z);
    g.rotation.set(r, p, w, 'ZYX');
    return g;
  }
  function visual(v, colours) {
    const shape = v.querySelector('geometry > *');
    if (!shape) return null;
    const a = (name) => Number(shape.getAttribute(name));
    let geometry;
    if (shape.tagName === 'box') geometry = new T.BoxBufferGeometry(...nums(shape.getAttribute('size')));
    else if (shape.tagName === 'sphere') geometry = new T.SphereBufferGeometry(a('radius'), 16, 12);
    else if (shape.tagName === 'cylinder') {
      geometry = new T.CylinderBufferGeometry(a('radius'), a('radius'), a('length'), 24);
      geometry.rotateX(Math.PI / 2);  // three.js's cylinders stand on y, URDF's on z
    } else return null;  // meshes: the rbx1 URDF has none
    const mat = v.querySelector('material');
    const colour = mat && (mat.querySelector('color') ? nums(mat.querySelector('color').getAttribute('rgba'))
                                                       : colours[mat.getAttribute('name')]);
    const material = new T.MeshStandardMaterial({ color: colour ? new T.Color(...colour.slice(0, 3)) : 0xb0b0b8,
                                                  metalness: 0.2, roughness: 0.55 });
    const g = placed(v.querySelector('origin'));
    g.add(new T.Mesh(geometry, material));
    return g;
  }
  function robotFromUrdf(text) {
    const doc = new DOMParser().parseFromString(text, 'application/xml');
    const colours = {};
    for (const mat of doc.querySelectorAll('robot > material')) {
      const c = mat.querySelector('color');
      if (c) colours[mat.getAttribute('name')] = nums(c.getAttribute('rgba'));
    }
    const links = {};
    for (const l of doc.querySelectorAll('robot > link')) {
      const g = new T.Group();
      g.name = l.getAttribute('name');
      for (const v of l.querySelectorAll(':scope > visual')) {
        const shape = visual(v, colours);
        if (shape) g.add(shape);
      }
      links[g.name] = g;
    }
    const joints = {}, children = new Set();
    for (const j of doc.querySelectorAll('robot > joint')) {
      const parent = j.querySelector('parent').getAttribute('link'), child = j.querySelector('child').getAttribute('link');
      const at = placed(j.querySelector('origin')), mover = new T.Group();
      at.add(mover);
      mover.add(links[child]);
      links[parent].add(at);
      children.add(child);
      const axis = j.querySelector('axis'), mimic = j.querySelector('mimic');
      joints[j.getAttribute('name')] = {
        type: j.getAttribute('type'), mover,
        axis: new T.Vector3(...nums(axis ? axis.getAttribute('xyz') : '1 0 0')).normalize(),
        mimic: mimic && { joint: mimic.getAttribute('joint'), k: Number(mimic.getAttribute('multiplier') || 1),
                          offset: Number(mimic.getAttribute('offset') || 0) },
      };
    }
    const root = Object.values(links).find((g) => !children.has(g.name));
    return { root, joints, revolute: Object.keys(joints).filter((n) => joints[n].type === 'revolute') };
  }
  function setJoint(j, q) {
    if (j.type === 'prismatic') j.mover.position.copy(j.axis).multiplyScalar(q);
    else if (j.type !== 'fixed') j.mover.quaternion.setFromAxisAngle(j.axis, q);
  }

  // ---- the joints from the status: joints_deg in the URDF's revolute order, the finger from the servo pulse ---
  function showStatus(s) {
    const r = view.robot;
    if (!r || !Array.isArray(s.joints_deg)) return;
    const values = {};
    r.revolute.forEach((name, i) => { values[name] = (s.joints_deg[i] || 0) * Math.PI / 180; });
    const g = view.scene && view.scene.gripper, us = s.firmware && s.firmware.gripper_us;
    if (g && typeof us === 'number') {  // the inverse of the gripper's pulse (host/arm urdf.cpp finger_position_m)
      const opening = Math.min(Math.max((us - g.closed_us) / ((g.open_us - g.closed_us) || 1), 0), 1) * g.max_opening_mm;
      values.finger_left_joint = m(opening / 2);
      view.finger_m = values.finger_left_joint;
    }
    for (const [name, j] of Object.entries(r.joints)) {
      if (j.mimic && j.mimic.joint in values) setJoint(j, values[j.mimic.joint] * j.mimic.k + j.mimic.offset);
      else if (name in values) setJoint(j, values[name]);
    }
    view.joints_deg = s.joints_deg.slice();
    render();
  }

  // ---- the world around it (GET /api/scene, millimetres in the base frame) -----------------------------------
  function text(label, colour) {
    const c = document.createElement('canvas');
    c.width = 256;
    c.height = 64;
    const g = c.getContext('2d');
    g.font = 'bold 30px sans-serif';
    g.fillStyle = colour;
    g.textAlign = 'center';
    g.textBaseline = 'middle';
    g.fillText(label, 128, 32);
    const s = new T.Sprite(new T.SpriteMaterial({ map: new T.CanvasTexture(c), depthTest: false }));
    s.scale.set(0.12, 0.03, 1);
    return s;
  }
  function lines(points, colour) {  // points: [[x, y, z] mm, ...] joined in order
    const g = new T.BufferGeometry().setFromPoints(points.map((p) => new T.Vector3(m(p[0]), m(p[1]), m(p[2]))));
    return new T.Line(g, new T.LineBasicMaterial({ color: colour }));
  }
  function flatBox(x, y, z, w, l, h, yawDeg, colour, opacity) {
    const mesh = new T.Mesh(new T.BoxBufferGeometry(m(w), m(l), m(h)),
                            new T.MeshLambertMaterial({ color: colour, transparent: opacity < 1, opacity }));
    mesh.position.set(m(x), m(y), m(z + h / 2));
    mesh.rotation.z = yawDeg * Math.PI / 180;
    return mesh;
  }
  function table(sc) {
    // The table under everything drawn on it: the arm's base, the places, the camera's view.
    const xs = [-150, 150], ys = [-150, 150];
    for (const p of sc.places) { xs.push(p.x_mm); ys.push(p.y_mm); }
    for (const c of sc.view.corners_mm || []) { xs.push(c[0]); ys.push(c[1]); }
    const [x0, x1, y0, y1] = [Math.min(...xs) - 80, Math.max(...xs) + 80, Math.min(...ys) - 80, Math.max(...ys) + 80];
    const top = flatBox((x0 + x1) / 2, (y0 + y1) / 2, sc.table_z_mm - 10, x1 - x0, y1 - y0, 10, 0, 0xd8c8a8, 1);
    const grid = new T.GridHelper(m(Math.max(x1 - x0, y1 - y0)), Math.round(Math.max(x1 - x0, y1 - y0) / 50), 0xb8a888, 0xc8b898);
    grid.rotation.x = Math.PI / 2;  // GridHelper lies in x-z; the table in x-y
    grid.position.set(m((x0 + x1) / 2), m((y0 + y1) / 2), m(sc.table_z_mm) + 0.0005);
    return [top, grid];
  }
  function showScene(sc) {
    view.scene = sc;
    world.remove(...world.children);
    world.add(...table(sc));
    for (const p of sc.places) {
      world.add(flatBox(p.x_mm, p.y_mm, p.z_mm, 70, 70, 2, p.yaw_deg, 0x3b6fd8, 0.6));
      const t = text(p.name, '#1d3f8a');
      t.position.set(m(p.x_mm), m(p.y_mm), m(p.z_mm) + 0.03);
      world.add(t);
    }
    const v = sc.view;  // the camera at the scan pose and what it sees of the table
    if (v.corners_mm) {
      const c = v.corners_mm;
      world.add(lines([...c, c[0]], 0xe07a10));
      for (const corner of c) world.add(lines([v.apex_mm, corner], 0xe07a10));
    }
    for (const o of sc.objects) {
      world.add(flatBox(o.x_mm, o.y_mm, o.z_mm, o.opening_mm, o.length_mm, 12, o.yaw_deg, o.feasible ? 0x2e9e4f : 0xc0392b, 1));
      const t = text(o.label || '#' + o.index, '#185c2c');
      t.position.set(m(o.x_mm), m(o.y_mm), m(o.z_mm) + 0.04);
      world.add(t);
    }
    view.objects = sc.objects.length;
    box.dataset.objects = sc.objects.length;
    if (!view.robot) {
      view.robot = robotFromUrdf(sc.urdf);
      scene.add(view.robot.root);
    }
    render();
  }
  async function get(url) {  // with the console's token (console.js's headers())
    return (await fetch(url, { headers: typeof headers === 'function' ? headers(false) : {} })).json();
  }
  async function loadScene() {
    try {
      const j = await get('/api/scene');
      if (!j.result) return;
      showScene(j.result);
      const s = await get('/api/status');  // the stream's status may have come before the arm was built
      if (s.result && !view.joints_deg) showStatus(s.result);
    } catch (e) { /* the status badge says when rbx1d is away */ }
  }

  // ---- a pick's plan: the tool point at each of its moves, from where the arm stands ---------------------------
  function showPlan(e) {
    path.remove(...path.children);
    const points = (e.waypoints || []).filter((w) => Array.isArray(w.tool_mm)).map((w) => w.tool_mm);
    view.path = points;
    view.path_drawn_ms = Date.now();
    box.dataset.path = points.length;
    if (points.length > 1) path.add(lines(points, 0xc0189a));
    for (const p of points) {
      const dot = new T.Mesh(new T.SphereBufferGeometry(0.006, 10, 8), new T.MeshBasicMaterial({ color: 0xc0189a }));
      dot.position.set(m(p[0]), m(p[1]), m(p[2]));
      path.add(dot);
    }
    render();
  }

  // console.js hands on the event stream: every log line (rbx1-event) and the arm's status (rbx1-status).
  const changesScene = new Set(['place_save', 'pose_save', 'calibrate_workspace']);
  document.addEventListener('rbx1-status', (ev) => showStatus(ev.detail));
  document.addEventListener('rbx1-event', (ev) => {
    const e = ev.detail;
    if (e.event === 'planned') showPlan(e);
    if (e.scan !== undefined || (e.result !== undefined && changesScene.has(e.cmd))) loadScene();
  });
  document.getElementById('token').addEventListener('change', loadScene);
  resize();
  loadScene();
})();
