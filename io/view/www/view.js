// The live view of a growing flysfm model (docs/view.md). Messages arrive as
// server-sent events: `model` (everything, on connect and after an overflow),
// `update` (what one image changed), `end`. Applying an update costs what it
// changed: points live in preallocated buffers with an id -> slot map, a
// removed point's slot is filled by the last point, and only the span of
// slots touched is uploaded again.
(function () {
  'use strict';
  const state = window.flysfmView;
  const query = location.search;
  const $ = function (id) { return document.getElementById(id); };

  const originalError = console.error;
  console.error = function () {
    state.errors.push(Array.prototype.map.call(arguments, String).join(' '));
    originalError.apply(console, arguments);
  };

  // --- scene ---------------------------------------------------------------
  const canvas = $('scene');
  let renderer;
  try {
    renderer = new THREE.WebGLRenderer({ canvas: canvas, antialias: false });
  } catch (e) {
    state.errors.push('WebGL unavailable: ' + e.message);
    $('status').textContent = 'WebGL unavailable';
    return;
  }
  renderer.setPixelRatio(window.devicePixelRatio || 1);
  const scene = new THREE.Scene();
  scene.background = new THREE.Color(0x111111);
  const camera = new THREE.PerspectiveCamera(50, 1, 0.001, 1e6);
  camera.position.set(0, 0, 10);
  const controls = new THREE.OrbitControls(camera, canvas);
  controls.screenSpacePanning = true;
  // The model's frame is a camera's: x right, y down, z forward. Turned half
  // a turn about x, the first camera looks into the screen with y up.
  const root = new THREE.Group();
  root.rotation.x = Math.PI;
  scene.add(root);

  // --- points --------------------------------------------------------------
  let capacity = 0;
  let count = 0;
  let positions = new Float32Array(0);
  let colors = new Uint8Array(0);      // what is drawn: by the colouring chosen
  let photoColors = new Uint8Array(0); // the points' own colours
  // The points' quality measures (docs/quality.md), when the run sends them.
  let views = new Uint16Array(0);
  let angles = new Float32Array(0);
  let sigmas = new Float32Array(0);    // NaN: undefined
  let slotIds = [];             // slot -> point id
  const slotOf = new Map();     // point id -> slot
  let dirtyLow = Infinity;
  let dirtyHigh = -1;
  const pointMaterial = new THREE.PointsMaterial({
    size: 2, sizeAttenuation: false, vertexColors: THREE.VertexColors });
  let geometry = new THREE.BufferGeometry();
  const cloud = new THREE.Points(geometry, pointMaterial);
  cloud.frustumCulled = false;  // the bounding sphere is never recomputed
  root.add(cloud);

  function allocate(wanted) {
    let size = Math.max(1024, capacity);
    while (size < wanted) size *= 2;
    const newPositions = new Float32Array(3 * size);
    const newColors = new Uint8Array(3 * size);
    const newPhotoColors = new Uint8Array(3 * size);
    const newViews = new Uint16Array(size);
    const newAngles = new Float32Array(size);
    const newSigmas = new Float32Array(size);
    newPositions.set(positions.subarray(0, 3 * count));
    newColors.set(colors.subarray(0, 3 * count));
    newPhotoColors.set(photoColors.subarray(0, 3 * count));
    newViews.set(views.subarray(0, count));
    newAngles.set(angles.subarray(0, count));
    newSigmas.set(sigmas.subarray(0, count));
    positions = newPositions;
    colors = newColors;
    photoColors = newPhotoColors;
    views = newViews;
    angles = newAngles;
    sigmas = newSigmas;
    capacity = size;
    geometry.dispose();
    geometry = new THREE.BufferGeometry();
    const position = new THREE.BufferAttribute(positions, 3);
    const color = new THREE.BufferAttribute(colors, 3, true);
    position.setUsage(THREE.DynamicDrawUsage);
    color.setUsage(THREE.DynamicDrawUsage);
    geometry.setAttribute('position', position);
    geometry.setAttribute('color', color);
    cloud.geometry = geometry;
    dirtyLow = 0;
    dirtyHigh = count - 1;
  }

  function touch(slot) {
    if (slot < dirtyLow) dirtyLow = slot;
    if (slot > dirtyHigh) dirtyHigh = slot;
  }

  // --- colouring: the points' own colour, their coverage, their uncertainty
  // Coverage follows the run's rule ("coverage" in the messages): well
  // covered (green) with at least min_views images and a largest angle of
  // min_angle_deg; enough images at too narrow an angle (orange); too few
  // images (red). Uncertainty: log sigma from green (the model's 5th
  // percentile) through yellow to red (its 95th); undefined in magenta.
  let colouring = 'colour';
  let rule = null;            // {min_views, min_angle_deg}
  let wellCovered = 0;        // points well covered, kept per point set/removed
  let rampLow = 0;            // log10 sigma at green
  let rampHigh = 1;           // log10 sigma at red
  let rampCount = -1;         // the point count the ramp was fitted at

  function isWell(slot) {
    return rule !== null && views[slot] >= rule.min_views && angles[slot] >= rule.min_angle_deg;
  }

  function paint(slot) {
    const o = 3 * slot;
    let r = photoColors[o], g = photoColors[o + 1], b = photoColors[o + 2];
    if (colouring === 'coverage' && rule !== null) {
      if (isWell(slot)) { r = 40; g = 200; b = 70; }
      else if (views[slot] >= rule.min_views) { r = 255; g = 150; b = 20; }
      else { r = 230; g = 40; b = 40; }
    } else if (colouring === 'uncertainty') {
      const sigma = sigmas[slot];
      if (!(sigma > 0)) {
        r = 220; g = 60; b = 220;
      } else {
        const t = Math.min(1, Math.max(0, (Math.log10(sigma) - rampLow) /
                                              Math.max(1e-9, rampHigh - rampLow)));
        // green -> yellow -> red
        r = Math.round(t < 0.5 ? 510 * t : 255);
        g = Math.round(t < 0.5 ? 200 + 110 * t : 255 * (2 - 2 * t));
        b = 40;
      }
    }
    colors[o] = r; colors[o + 1] = g; colors[o + 2] = b;
  }

  // The ramp from about 2000 sigmas spread over the slots: its cost does not
  // grow with the model.
  function fitRamp() {
    const sample = [];
    const step = Math.max(1, Math.floor(count / 2000));
    for (let i = 0; i < count; i += step) {
      if (sigmas[i] > 0) sample.push(Math.log10(sigmas[i]));
    }
    rampCount = count;
    if (sample.length === 0) return;
    sample.sort(function (p, q) { return p - q; });
    rampLow = sample[Math.floor(0.05 * (sample.length - 1))];
    rampHigh = sample[Math.ceil(0.95 * (sample.length - 1))];
    state.uncertaintyRange = [Math.pow(10, rampLow), Math.pow(10, rampHigh)];
  }

  function paintAll() {
    for (let slot = 0; slot < count; ++slot) paint(slot);
    dirtyLow = 0;
    dirtyHigh = count - 1;
  }

  function setPoint(points, i) {
    const id = points.ids[i];
    let slot = slotOf.get(id);
    if (slot === undefined) {
      if (count === capacity) allocate(count + 1);
      slot = count++;
      slotOf.set(id, slot);
      slotIds[slot] = id;
    } else if (isWell(slot)) {
      --wellCovered;
    }
    for (let k = 0; k < 3; ++k) {
      const value = points.xyz[3 * i + k];
      positions[3 * slot + k] = value === null ? 0 : value;
      photoColors[3 * slot + k] = points.rgb[3 * i + k];
    }
    if (points.views) {
      views[slot] = points.views[i];
      angles[slot] = points.angle[i] === null ? 0 : points.angle[i];
      sigmas[slot] = points.sigma[i] === null ? NaN : points.sigma[i];
    } else {
      views[slot] = 0;
      angles[slot] = 0;
      sigmas[slot] = NaN;
    }
    if (isWell(slot)) ++wellCovered;
    paint(slot);
    touch(slot);
  }

  function removePoint(id) {
    const slot = slotOf.get(id);
    if (slot === undefined) return;
    const last = count - 1;
    if (slot === last && isWell(slot)) --wellCovered;
    if (slot !== last) {
      const moved = slotIds[last];
      if (isWell(slot)) --wellCovered;
      positions.copyWithin(3 * slot, 3 * last, 3 * last + 3);
      colors.copyWithin(3 * slot, 3 * last, 3 * last + 3);
      photoColors.copyWithin(3 * slot, 3 * last, 3 * last + 3);
      views[slot] = views[last];
      angles[slot] = angles[last];
      sigmas[slot] = sigmas[last];
      slotIds[slot] = moved;
      slotOf.set(moved, slot);
      touch(slot);
    }
    slotIds.length = last;
    slotOf.delete(id);
    count = last;
  }

  function clearPoints() {
    slotOf.clear();
    slotIds = [];
    count = 0;
    wellCovered = 0;
  }

  function uploadPoints() {
    geometry.setDrawRange(0, count);
    if (dirtyHigh >= dirtyLow && geometry.attributes.position) {
      const position = geometry.attributes.position;
      const color = geometry.attributes.color;
      const low = Math.min(dirtyLow, count);
      const high = Math.min(dirtyHigh, count - 1);
      if (high >= low) {
        position.updateRange = { offset: 3 * low, count: 3 * (high - low + 1) };
        color.updateRange = { offset: 3 * low, count: 3 * (high - low + 1) };
        position.needsUpdate = true;
        color.needsUpdate = true;
      }
    }
    dirtyLow = Infinity;
    dirtyHigh = -1;
  }

  // --- cameras -------------------------------------------------------------
  const cameraMaterial = new THREE.LineBasicMaterial({ color: 0x4da6ff });
  const newestMaterial = new THREE.LineBasicMaterial({ color: 0xff8c1a });
  const frustumGeometry = new Map();  // camera_id -> geometry, shared by its images
  const frustums = new Map();         // image id -> LineSegments
  let newestId = null;
  let frustumScale = 1;

  function makeFrustumGeometry(k) {
    const w = k.width > 0 ? k.width : 4;
    const h = k.height > 0 ? k.height : 3;
    const f = k.focal > 0 ? k.focal : Math.max(w, h);
    const x = w / (2 * f);
    const y = h / (2 * f);
    const c = [[-x, -y, 1], [x, -y, 1], [x, y, 1], [-x, y, 1]];
    const v = [];
    for (let i = 0; i < 4; ++i) {
      v.push(0, 0, 0, c[i][0], c[i][1], c[i][2]);
      const j = (i + 1) % 4;
      v.push(c[i][0], c[i][1], c[i][2], c[j][0], c[j][1], c[j][2]);
    }
    // A tick on the image's top edge (y is down): which way is up.
    v.push(-x * 0.4, -y, 1, 0, -y * 1.4, 1, 0, -y * 1.4, 1, x * 0.4, -y, 1);
    const g = new THREE.BufferGeometry();
    g.setAttribute('position', new THREE.Float32BufferAttribute(v, 3));
    return g;
  }

  function geometryFor(cameraId) {
    let g = frustumGeometry.get(cameraId);
    if (!g) {
      g = makeFrustumGeometry({ width: 4, height: 3, focal: 4 });
      frustumGeometry.set(cameraId, g);
    }
    return g;
  }

  function setIntrinsics(list) {
    for (const k of list) {
      const g = makeFrustumGeometry(k);
      const old = frustumGeometry.get(k.camera_id);
      frustumGeometry.set(k.camera_id, g);
      if (old) {
        frustums.forEach(function (object) {
          if (object.userData.cameraId === k.camera_id) object.geometry = g;
        });
        old.dispose();
      }
    }
  }

  // The first sub-model in the cameras' colour, each other one in its own
  // until it merges (its cameras then come again with the survivor's id).
  const subModelColours = [0x4da6ff, 0x44dd88, 0xffd23f, 0xff5c8a, 0xa0a0ff, 0x3fe0d0];
  const subModelMaterials = new Map();  // sub-model id -> material
  function materialFor(model) {
    if (model === undefined || model <= 1) return cameraMaterial;
    let material = subModelMaterials.get(model);
    if (!material) {
      material = new THREE.LineBasicMaterial(
        { color: subModelColours[(model - 1) % subModelColours.length] });
      subModelMaterials.set(model, material);
    }
    return material;
  }

  function setCamera(c) {
    let object = frustums.get(c.id);
    if (!object) {
      object = new THREE.LineSegments(geometryFor(c.camera_id), materialFor(c.model));
      object.userData.cameraId = c.camera_id;
      object.scale.setScalar(frustumScale);
      frustums.set(c.id, object);
      root.add(object);
    }
    object.userData.model = c.model;
    if (object.material !== newestMaterial) object.material = materialFor(c.model);
    // cam_from_world (R, t): the camera's centre is -R^T t, its orientation R^T.
    const q = new THREE.Quaternion(c.q[0], c.q[1], c.q[2], c.q[3]).normalize();
    const inverse = q.clone().conjugate();
    const centre = new THREE.Vector3(c.t[0], c.t[1], c.t[2]).applyQuaternion(inverse).negate();
    object.quaternion.copy(inverse);
    object.position.copy(centre);
    object.userData.name = c.name;
  }

  function removeCamera(id) {
    const object = frustums.get(id);
    if (!object) return;
    root.remove(object);
    frustums.delete(id);
    if (newestId === id) newestId = null;
  }

  function setNewest(id) {
    if (newestId !== null && frustums.has(newestId)) {
      const previous = frustums.get(newestId);
      previous.material = materialFor(previous.userData.model);
    }
    newestId = frustums.has(id) ? id : null;
    if (newestId !== null) frustums.get(newestId).material = newestMaterial;
  }

  // Frustums sized to the spread of the camera centres: visible from afar,
  // small beside the points. O(cameras), which is small.
  function rescaleFrustums() {
    const box = new THREE.Box3();
    frustums.forEach(function (object) { box.expandByPoint(object.position); });
    const size = frustums.size > 1 ? box.getSize(new THREE.Vector3()).length() : 0;
    frustumScale = size > 0 ? 0.08 * size : 0.3;
    frustums.forEach(function (object) { object.scale.setScalar(frustumScale); });
    for (const ghost of ghosts) ghost.scale.setScalar(1.5 * frustumScale);
  }

  // --- level of detail while moving --------------------------------------
  // While the view moves, frames should take about `movingFrameMs`: when the
  // last still frame (every point) took longer, every k-th slot is drawn
  // instead, through an index over the same buffers, and the whole cloud
  // again once the view stops. A million points on a tablet's GPU, or on a
  // CPU without one, would otherwise make orbiting a slide show; a GPU that
  // draws them all in time draws them all while moving too.
  const movingFrameMs = 30;
  // Milliseconds per drawn point, from the frames measured (smoothed).
  let msPerPoint = 0;
  let moving = false;
  let lodGeometry = null;
  let lodCount = -1;
  let lodStep = 1;
  function movingStep() {
    if (msPerPoint * count <= movingFrameMs) return 1;
    const budget = Math.max(20000, movingFrameMs / msPerPoint);
    return Math.max(1, Math.ceil(count / budget));
  }
  function movingGeometry() {
    const step = movingStep();
    if (step <= 1) return geometry;
    if (!lodGeometry || lodCount !== count || lodStep !== step ||
        lodGeometry.attributes.position !== geometry.attributes.position) {
      const index = new Uint32Array(Math.ceil(count / step));
      for (let j = 0; j < index.length; ++j) index[j] = j * step;
      if (lodGeometry) {
        // Its buffers are the cloud's: only the index is its own to free.
        lodGeometry.deleteAttribute('position');
        lodGeometry.deleteAttribute('color');
        lodGeometry.dispose();
      }
      lodGeometry = new THREE.BufferGeometry();
      lodGeometry.setAttribute('position', geometry.attributes.position);
      lodGeometry.setAttribute('color', geometry.attributes.color);
      lodGeometry.setIndex(new THREE.BufferAttribute(index, 1));
      lodCount = count;
      lodStep = step;
    }
    return lodGeometry;
  }

  // --- the coverage surface and the suggested viewpoints -------------------
  // Faces coloured by their coverage (FaceClassColour in quality/coverage.cc:
  // well covered, too narrow an angle, too few views, underside, out of
  // reach), half
  // transparent over the points; each suggestion a magenta ghost camera.
  const faceColours = [[40, 200, 70], [255, 150, 20], [230, 40, 40], [128, 128, 128],
                       [110, 140, 190]];
  const surfaceMaterial = new THREE.MeshBasicMaterial({
    vertexColors: THREE.VertexColors, transparent: true, opacity: 0.45,
    side: THREE.DoubleSide, depthWrite: false });
  const ghostMaterial = new THREE.LineBasicMaterial({ color: 0xee55ff });
  let surfaceMesh = null;
  const ghosts = [];

  function setSurface(surface) {
    if (surfaceMesh) {
      root.remove(surfaceMesh);
      surfaceMesh.geometry.dispose();
      surfaceMesh = null;
    }
    const faces = surface.classes.length;
    if (faces > 0) {
      const g = new THREE.BufferGeometry();
      g.setAttribute('position', new THREE.BufferAttribute(new Float32Array(surface.xyz), 3));
      const rgb = new Uint8Array(9 * faces);
      for (let f = 0; f < faces; ++f) {
        const c = faceColours[surface.classes[f]] || [0, 0, 0];
        for (let v = 0; v < 3; ++v) rgb.set(c, 9 * f + 3 * v);
      }
      g.setAttribute('color', new THREE.BufferAttribute(rgb, 3, true));
      surfaceMesh = new THREE.Mesh(g, surfaceMaterial);
      surfaceMesh.frustumCulled = false;
      surfaceMesh.visible = $('show-surface').checked;
      root.add(surfaceMesh);
    }
    for (const ghost of ghosts) root.remove(ghost);
    ghosts.length = 0;
    const list = $('suggestions');
    list.textContent = '';
    for (const s of surface.suggestions) {
      const ghost = new THREE.LineSegments(geometryFor(firstCameraId()), ghostMaterial);
      const q = new THREE.Quaternion(s.q[0], s.q[1], s.q[2], s.q[3]).normalize();
      const inverse = q.clone().conjugate();
      ghost.quaternion.copy(inverse);
      ghost.position.copy(new THREE.Vector3(s.t[0], s.t[1], s.t[2]).applyQuaternion(inverse).negate());
      ghost.scale.setScalar(1.5 * frustumScale);
      ghosts.push(ghost);
      root.add(ghost);
      const li = document.createElement('li');
      li.textContent = s.reason;
      list.appendChild(li);
    }
    $('suggestions-count').textContent = String(surface.suggestions.length);
    $('surface-share').innerHTML = faces > 0 ?
      'well covered: <b>' + Math.round(100 * surface.share) + ' %</b> of its area' : '';
    state.surfaceFaces = faces;
    state.surfaceShare = faces > 0 ? surface.share : null;
    state.suggestions = surface.suggestions.map(function (s) { return s.reason; });
    state.ghosts = ghosts.length;
  }

  function firstCameraId() {
    for (const id of frustumGeometry.keys()) return id;
    return 1;
  }

  $('show-surface').addEventListener('change', function () {
    if (surfaceMesh) surfaceMesh.visible = $('show-surface').checked;
    requestRender();
  });

  // --- what the user sees --------------------------------------------------
  let userMoved = false;
  let follow = false;
  controls.addEventListener('start', function () { userMoved = true; follow = false;
    moving = true; });
  controls.addEventListener('end', function () { moving = false; requestRender(); });
  controls.addEventListener('change', requestRender);

  function worldCentre(object) {
    return root.localToWorld(object.position.clone());
  }

  function fitAll() {
    root.updateMatrixWorld(true);
    const box = new THREE.Box3();
    frustums.forEach(function (object) { box.expandByPoint(worldCentre(object)); });
    // About a thousand points, evenly through the slots: the cost of a fit
    // does not grow with the model. The farthest 5 % on each axis are left
    // out, so that a few stray points do not shrink the model to a dot.
    if (count > 0) {
      const xs = [], ys = [], zs = [];
      const step = Math.max(1, Math.floor(count / 1000));
      const v = new THREE.Vector3();
      for (let i = 0; i < count; i += step) {
        root.localToWorld(v.set(positions[3 * i], positions[3 * i + 1], positions[3 * i + 2]));
        xs.push(v.x); ys.push(v.y); zs.push(v.z);
      }
      const sorted = [xs, ys, zs].map(function (a) { return a.sort(function (p, q) { return p - q; }); });
      const low = Math.floor(0.05 * (xs.length - 1));
      const high = Math.ceil(0.95 * (xs.length - 1));
      box.expandByPoint(new THREE.Vector3(sorted[0][low], sorted[1][low], sorted[2][low]));
      box.expandByPoint(new THREE.Vector3(sorted[0][high], sorted[1][high], sorted[2][high]));
    }
    if (box.isEmpty()) return;
    const centre = box.getCenter(new THREE.Vector3());
    const radius = Math.max(box.getSize(new THREE.Vector3()).length(), 4 * frustumScale, 1e-3);
    controls.target.copy(centre);
    camera.position.copy(centre).add(new THREE.Vector3(0, 0.25 * radius, 0.75 * radius));
    camera.near = radius / 1000;
    camera.far = radius * 1000;
    camera.updateProjectionMatrix();
    controls.update();
  }

  function followNewest() {
    if (newestId === null) return;
    root.updateMatrixWorld(true);
    const object = frustums.get(newestId);
    const centre = worldCentre(object);
    // Behind and above the newest camera, looking where it looks.
    const forward = new THREE.Vector3(0, 0, 1).applyQuaternion(object.getWorldQuaternion(
      new THREE.Quaternion()));
    const up = new THREE.Vector3(0, -1, 0).applyQuaternion(object.getWorldQuaternion(
      new THREE.Quaternion()));
    const distance = 6 * frustumScale;
    controls.target.copy(centre).addScaledVector(forward, distance);
    camera.position.copy(centre).addScaledVector(forward, -distance).addScaledVector(up, distance);
    controls.update();
  }

  $('follow').addEventListener('click', function () {
    follow = true;
    userMoved = true;
    followNewest();
    requestRender();
  });
  $('fit').addEventListener('click', function () {
    follow = false;
    fitAll();
    requestRender();
  });

  // A pending or rejected shot's thumbnail, made once per shot and kept
  // across list changes so that a long list is not fetched again on each.
  // The server has none for a shot it never decoded, or when it serves a
  // finished run: the picture then hides and the name and reason stay.
  const listThumbnails = new Map();
  function listThumbnail(name) {
    let img = listThumbnails.get(name);
    if (!img) {
      img = document.createElement('img');
      img.className = 'shot';
      img.alt = name;
      img.loading = 'lazy';
      img.onerror = function () { img.style.display = 'none'; };
      img.src = 'thumbnail.jpg' + (query ? query + '&' : '?') + 'name=' +
        encodeURIComponent(name);
      listThumbnails.set(name, img);
    }
    return img;
  }

  function showList(id, list) {
    const ul = $(id);
    ul.textContent = '';
    for (const item of list) {
      const li = document.createElement('li');
      li.appendChild(listThumbnail(item.name));
      const text = document.createElement('span');
      text.textContent = item.reason ? item.name + ': ' + item.reason : item.name;
      li.appendChild(text);
      ul.appendChild(li);
    }
    $(id + '-count').textContent = String(list.length);
    // Shots in neither list (registered since) let their pictures go.
    const listed = new Set();
    for (const other of ['pending', 'rejected']) {
      for (const li of $(other).children) listed.add(li.firstChild.alt);
    }
    for (const name of Array.from(listThumbnails.keys())) {
      if (!listed.has(name)) listThumbnails.delete(name);
    }
  }

  let shots = 0;
  function showLine(line) {
    if (!line) return;
    const parts = [line.name, line.status, line.points + ' pts', (line.new_points >= 0 ? '+' : '') +
                   line.new_points + ' new', Math.round(line.ms) + ' ms'];
    if (line.delay_ms !== null && line.delay_ms !== undefined) {
      parts.push('delay ' + Math.round(line.delay_ms) + ' ms');
    }
    if (line.model) parts.push(line.model);
    if (line.reason) parts.push(line.reason);
    $('line').textContent = parts.join('  ');
    $('line').className = line.status;
    // Several photographers: the name starts with the tag; the tooltip says so.
    $('line').title = line.source ? 'from source ' + line.source : '';
  }

  function showThumbnail() {
    const img = $('thumbnail');
    img.onload = function () { img.style.display = 'block'; };
    img.src = 'thumbnail.jpg' + (query ? query + '&' : '?') + 'n=' + (++shots);
  }

  function showCounts(counts) {
    $('images').textContent = String(counts.images);
    $('points').textContent = String(counts.points);
    state.images = Number($('images').textContent);
    state.modelPoints = Number($('points').textContent);
  }

  // --- messages ------------------------------------------------------------
  function applyPoints(points) {
    for (let i = 0; i < points.ids.length; ++i) setPoint(points, i);
  }

  // The run's coverage rule: the first message that carries one enables the
  // coverage and uncertainty colourings.
  function setRule(coverage) {
    if (!coverage) return;
    const changed = rule === null || rule.min_views !== coverage.min_views ||
                    rule.min_angle_deg !== coverage.min_angle_deg;
    rule = { min_views: coverage.min_views, min_angle_deg: coverage.min_angle_deg };
    state.measured = true;
    for (const option of $('colouring').options) option.disabled = false;
    if (changed) {
      wellCovered = 0;
      for (let slot = 0; slot < count; ++slot) if (isWell(slot)) ++wellCovered;
    }
  }

  function showColouring() {
    const legend = $('legend');
    if (colouring === 'coverage' && rule !== null) {
      legend.innerHTML = '<span style="background:#28c846"></span>well covered' +
        '<span style="background:#ff9614"></span>angle &lt; ' + rule.min_angle_deg + '&deg;' +
        '<span style="background:#e62828"></span>&lt; ' + rule.min_views + ' views';
    } else if (colouring === 'uncertainty') {
      const range = state.uncertaintyRange;
      legend.innerHTML = '<span style="background:#28c828"></span>' +
        (range ? range[0].toPrecision(2) : 'low') +
        '<span style="background:#ffff28"></span>' +
        '<span style="background:#ff0028"></span>' + (range ? range[1].toPrecision(2) : 'high') +
        ' (model units)<span style="background:#dc3cdc"></span>undefined';
    } else {
      legend.textContent = '';
    }
    state.wellCovered = wellCovered;
    state.wellCoveredShare = count > 0 ? wellCovered / count : 0;
    if (rule !== null) {
      $('coverage').innerHTML = 'Well covered: <b>' +
        Math.round(100 * state.wellCoveredShare) + ' %</b> of points (&ge; ' + rule.min_views +
        ' views, &ge; ' + rule.min_angle_deg + '&deg;)';
    }
  }

  function setColouring(mode) {
    colouring = mode;
    state.colouring = mode;
    if (mode === 'uncertainty') fitRamp();
    paintAll();
    uploadPoints();
    showColouring();
    requestRender();
  }
  $('colouring').addEventListener('change', function () { setColouring($('colouring').value); });
  // The drawn colours, r g b per point in slot order: what the browser test
  // compares with the run's measures.
  state.drawnColours = function () { return Array.from(colors.subarray(0, 3 * count)); };

  function onModel(m) {
    frustums.forEach(function (object) { root.remove(object); });
    frustums.clear();
    newestId = null;
    clearPoints();
    setIntrinsics(m.intrinsics);
    for (const c of m.cameras) setCamera(c);
    if (m.points.ids.length > capacity) allocate(m.points.ids.length);
    setRule(m.coverage);
    applyPoints(m.points);
    if (m.surface) setSurface(m.surface);
    showList('pending', m.pending);
    showList('rejected', m.rejected);
    showCounts(m.counts);
    showLine(m.line);
    let newest = null;
    for (const c of m.cameras) {
      if (m.line && c.name === m.line.name) newest = c.id;
    }
    if (newest === null && m.cameras.length > 0) newest = m.cameras[m.cameras.length - 1].id;
    rescaleFrustums();
    setNewest(newest);
    if (m.line) showThumbnail();
    if (m.finished) onEnd();
  }

  function onUpdate(m) {
    state.updates += 1;
    setRule(m.coverage);
    for (const id of m.removed_points) removePoint(id);
    applyPoints(m.points);
    if (m.surface) setSurface(m.surface);
    setIntrinsics(m.intrinsics);
    for (const id of m.removed_cameras) removeCamera(id);
    let newest = null;
    for (const c of m.cameras) {
      if (!frustums.has(c.id)) newest = c.id;
      setCamera(c);
    }
    if (m.cameras.length > 0 || m.removed_cameras.length > 0) rescaleFrustums();
    if (newest !== null) setNewest(newest);
    if (m.pending) showList('pending', m.pending);
    if (m.rejected) showList('rejected', m.rejected);
    showCounts(m.counts);
    if (m.lines.length > 0) {
      showLine(m.lines[m.lines.length - 1]);
      showThumbnail();
    }
  }

  // What a long step of the run is doing (the end's adjustment, say).
  function onStatus(m) {
    state.status = m.text;
    if (!state.finished) $('status').textContent = m.text || 'live';
  }

  let source = null;
  function onEnd() {
    state.finished = true;
    $('status').textContent = 'run finished';
    if (source) source.close();
  }

  function onMessage(event) {
    state.messages += 1;
    state.bytes += event.data.length;
    const m = JSON.parse(event.data);
    if (m.type === 'model') onModel(m);
    else if (m.type === 'update') onUpdate(m);
    else if (m.type === 'end') onEnd();
    else if (m.type === 'status') onStatus(m);
    // The uncertainty ramp follows the model as it grows (refitted when the
    // points grew by a tenth: the cost of repainting is then the model's).
    if (colouring === 'uncertainty' && Math.abs(count - rampCount) > 0.1 * rampCount) {
      fitRamp();
      paintAll();
    }
    showColouring();
    uploadPoints();
    state.cameras = frustums.size;
    state.points = count;
    if (follow) followNewest();
    else if (!userMoved) fitAll();
    requestRender();
  }

  source = new EventSource('events' + query);
  source.onopen = function () { $('status').textContent = 'live'; };
  source.onmessage = function (event) {
    try {
      onMessage(event);
    } catch (e) {
      state.errors.push('message: ' + e.message);
      throw e;
    }
  };
  source.onerror = function () {
    // EventSource reconnects by itself; the server then sends the model again.
    if (!state.finished) $('status').textContent = 'reconnecting';
  };

  // --- drawing: on demand, so that an idle view costs no battery -----------
  const gl = renderer.getContext();
  const recent = [];
  let lastDraw = 0;
  let wasMoving = false;
  let lastDrawn = 0;
  let pending = false;
  function resize() {
    const width = canvas.clientWidth;
    const height = canvas.clientHeight;
    if (canvas.width !== Math.floor(width * renderer.getPixelRatio()) ||
        canvas.height !== Math.floor(height * renderer.getPixelRatio())) {
      renderer.setSize(width, height, false);
      camera.aspect = width / Math.max(1, height);
      camera.updateProjectionMatrix();
    }
  }
  function draw() {
    pending = false;
    resize();
    cloud.geometry = moving ? movingGeometry() : geometry;
    const start = performance.now();
    renderer.render(scene, camera);
    gl.finish();  // the frame's time includes the GPU's
    // While moving, frames follow each other: the time from the last one is
    // what the user sees (a software GL may return from finish() before the
    // frame is on screen). A frame drawn on demand has only its own time.
    const now = performance.now();
    const chained = moving && wasMoving && now - lastDraw < 5000;
    const ms = chained ? now - lastDraw : now - start;
    const drawnNow = cloud.geometry === geometry ? count : lodGeometry.index.count;
    // A chained interval mostly paid for the previous frame's points.
    const paidFor = chained ? lastDrawn : drawnNow;
    lastDraw = now;
    lastDrawn = drawnNow;
    wasMoving = moving;
    if (paidFor >= 10000) {
      const sample = ms / paidFor;
      msPerPoint = msPerPoint === 0 ? sample : 0.7 * msPerPoint + 0.3 * sample;
    }
    recent.push(ms);
    if (recent.length > 30) recent.shift();
    state.frameMs = recent.reduce(function (a, b) { return a + b; }, 0) / recent.length;
    const drawn = drawnNow;
    if (moving) state.movingPoints = drawn;
    $('frame').textContent = 'frame: ' + state.frameMs.toFixed(1) + ' ms, ' + drawn + ' points drawn';
  }
  function requestRender() {
    if (pending) return;
    pending = true;
    requestAnimationFrame(draw);
  }
  window.addEventListener('resize', requestRender);

  // Orbits the view for `frames` frames and resolves to the mean frame time
  // in ms: the interactivity check of a large model (bench/bench_view.cc).
  // `still`: every point drawn, as when the view stops.
  state.measureFrames = function (frames, still) {
    return new Promise(function (resolve) {
      const times = [];
      let last = performance.now();
      moving = !still;
      function step() {
        controls.autoRotate = true;
        controls.update();
        draw();
        const now = performance.now();
        times.push(now - last);
        last = now;
        if (times.length < frames) {
          requestAnimationFrame(step);
        } else {
          controls.autoRotate = false;
          moving = false;
          requestRender();
          resolve(times.slice(1).reduce(function (a, b) { return a + b; }, 0) /
                  Math.max(1, times.length - 1));
        }
      }
      requestAnimationFrame(step);
    });
  };
  requestRender();
})();
