// The report's side-by-side 3D replay: two steppers' recorded trajectories
// of one scene, drawn with three.js (Debian's libjs-three, copied next to
// the report as three.min.js) in one canvas split in two, one camera for
// both. Bodies are drawn by their geoms; what the scene's "draw" hints
// name is drawn as what it stands for: cloth cells as one surface, hair
// segments as curves.
//
// report.html sets window.BLOCKSTEP_REPLAY_INDEX, a list of
// {scene, file, steppers}; each file (replay_<scene>.js, written by
// report.py) adds BLOCKSTEP_REPLAY[scene] = {scene, frameSeconds, runs}
// where a run's poses are little-endian int16, base64: per frame, per body,
// x y z (times positionScale) and, for bodies drawn by their geoms, the
// quaternion w x y z (times 32767).
//
// Opened as report.html?selftest, it loads every scene, draws its first
// and last frame and writes what it found (pixels drawn on each side,
// steppers listed, errors) as JSON into #selftest: the headless Chromium
// test reads it.
(function () {
  "use strict";

  const errors = [];
  window.addEventListener("error", (e) => errors.push(String(e.message || e)));
  const consoleError = console.error.bind(console);
  console.error = function (...args) {
    errors.push(args.map(String).join(" "));
    consoleError(...args);
  };

  const data = (window.BLOCKSTEP_REPLAY = window.BLOCKSTEP_REPLAY || {});
  const index = window.BLOCKSTEP_REPLAY_INDEX || [];
  const QUATERNION_SCALE = 32767;
  const BACKGROUND = 0xf4f4f0;

  // Scene data, loaded on demand (a script tag works from file://, where
  // fetch() of a local file does not).
  function loadScene(entry, done) {
    if (data[entry.scene]) return done(data[entry.scene]);
    const script = document.createElement("script");
    script.src = entry.file;
    script.onload = () => {
      if (!data[entry.scene]) errors.push(entry.file + " did not define " + entry.scene);
      done(data[entry.scene]);
    };
    script.onerror = () => {
      errors.push("cannot load " + entry.file);
      done(null);
    };
    document.head.appendChild(script);
  }

  function decodePoses(base64) {
    const text = atob(base64);
    const bytes = new Uint8Array(text.length);
    for (let i = 0; i < text.length; i++) bytes[i] = text.charCodeAt(i);
    return new Int16Array(bytes.buffer);
  }

  // Where each body's values start in a frame, and a frame's length.
  function layoutOf(scene) {
    const offsets = [];
    let size = 0;
    for (const body of scene.bodies) {
      offsets.push(size);
      size += body.pose;
    }
    return { offsets, frameSize: size };
  }

  const geometryCache = new Map();
  function cached(key, make) {
    if (!geometryCache.has(key)) geometryCache.set(key, make());
    return geometryCache.get(key);
  }

  // A geom as meshes; capsules and cylinders lie along z, as in ODE.
  function geomObject(geom, material) {
    const group = new THREE.Group();
    const alongZ = (g) => g.rotateX(Math.PI / 2);  // three.js makes them along y
    switch (geom.type) {
      case "box": {
        const [x, y, z] = geom.size;
        group.add(new THREE.Mesh(cached("box" + geom.size, () => new THREE.BoxBufferGeometry(x, y, z)), material));
        break;
      }
      case "sphere":
        group.add(new THREE.Mesh(cached("sphere" + geom.radius, () => new THREE.SphereBufferGeometry(geom.radius, 16, 12)), material));
        break;
      case "capsule":
      case "cylinder": {
        const r = geom.radius, l = geom.length;
        group.add(new THREE.Mesh(cached("cyl" + r + "," + l, () => alongZ(new THREE.CylinderBufferGeometry(r, r, l, 16))), material));
        if (geom.type === "capsule") {
          const ball = cached("sphere" + r, () => new THREE.SphereBufferGeometry(r, 16, 12));
          for (const end of [-0.5, 0.5]) {
            const cap = new THREE.Mesh(ball, material);
            cap.position.set(0, 0, end * l);
            group.add(cap);
          }
        }
        break;
      }
      default:
        break;  // planes are static only; unknown kinds are not drawn
    }
    return group;
  }

  function quaternionOf(q) {  // ODE's [w, x, y, z]
    return new THREE.Quaternion(q[1], q[2], q[3], q[0]);
  }

  // The static shapes: planes as a large square with a grid, the others
  // where they stand.
  function addStatics(scene, statics, extent) {
    const material = new THREE.MeshLambertMaterial({ color: 0xb9b3a6 });
    for (const s of statics) {
      if (s.type === "plane") {
        const normal = new THREE.Vector3(...s.normal).normalize();
        const turn = new THREE.Quaternion().setFromUnitVectors(new THREE.Vector3(0, 0, 1), normal);
        const size = 4 * extent;
        const plane = new THREE.Mesh(new THREE.PlaneBufferGeometry(size, size),
                                     new THREE.MeshLambertMaterial({ color: 0xd9d4c7 }));
        plane.quaternion.copy(turn);
        plane.position.copy(normal.clone().multiplyScalar(s.offset));
        scene.add(plane);
        const grid = new THREE.GridHelper(size, 40, 0xa8a294, 0xc4bfb2);
        grid.rotateX(Math.PI / 2);  // the helper lies in x-z
        grid.quaternion.premultiply(turn);
        grid.position.copy(normal.clone().multiplyScalar(s.offset + 1e-3));
        scene.add(grid);
        continue;
      }
      const object = geomObject(s, material);
      object.position.set(...s.position);
      if (s.quaternion) object.quaternion.copy(quaternionOf(s.quaternion));
      scene.add(object);
    }
  }

  // One side of the replay: a stepper's run of a scene.
  class RunView {
    constructor(sceneData, run, color) {
      const scene = sceneData.scene;
      this.layout = layoutOf(scene);
      this.poses = decodePoses(run.data);
      this.frames = run.frames;
      this.positionScale = run.positionScale;
      this.three = new THREE.Scene();
      this.three.background = new THREE.Color(BACKGROUND);
      this.three.add(new THREE.HemisphereLight(0xffffff, 0x707060, 0.8));
      const sun = new THREE.DirectionalLight(0xffffff, 0.6);
      sun.position.set(3, -4, 8);
      this.three.add(sun);
      addStatics(this.three, scene.static || [], sceneData.extent);
      const material = new THREE.MeshLambertMaterial({ color });
      this.bodies = [];
      scene.bodies.forEach((body, i) => {
        if (body.pose !== 7 || !body.geoms) return;
        const group = new THREE.Group();
        for (const g of body.geoms) group.add(geomObject(g, material));
        this.three.add(group);
        this.bodies.push({ index: i, object: group });
      });
      const draw = scene.draw || {};
      if (draw.surface) {
        const cols = draw.surface.columns, ids = draw.surface.bodies, rows = ids.length / cols;
        const geometry = new THREE.BufferGeometry();
        geometry.setAttribute("position", new THREE.BufferAttribute(new Float32Array(ids.length * 3), 3));
        const triangles = [];
        for (let r = 0; r + 1 < rows; r++)
          for (let c = 0; c + 1 < cols; c++) {
            const a = r * cols + c, b = a + 1, d = a + cols, e = d + 1;
            triangles.push(a, d, b, b, d, e);
          }
        geometry.setIndex(triangles);
        const cloth = new THREE.Mesh(geometry, new THREE.MeshLambertMaterial({ color, side: THREE.DoubleSide }));
        this.three.add(cloth);
        this.surface = { ids, geometry };
      }
      this.strands = (draw.strands || []).map((ids) => {
        const geometry = new THREE.BufferGeometry();
        geometry.setAttribute("position", new THREE.BufferAttribute(new Float32Array(ids.length * 3), 3));
        this.three.add(new THREE.Line(geometry, new THREE.LineBasicMaterial({ color })));
        // The bodies along it as dots: a one-pixel curve alone is hard to see.
        this.three.add(new THREE.Points(geometry, new THREE.PointsMaterial({ color, size: 4, sizeAttenuation: false })));
        return { ids, geometry };
      });
    }

    position(frame, body, out) {
      const k = frame * this.layout.frameSize + this.layout.offsets[body];
      const s = 1 / this.positionScale;
      out[0] = this.poses[k] * s;
      out[1] = this.poses[k + 1] * s;
      out[2] = this.poses[k + 2] * s;
      return out;
    }

    setFrame(frame) {
      frame = Math.min(frame, this.frames - 1);
      const p = [0, 0, 0];
      for (const { index, object } of this.bodies) {
        this.position(frame, index, p);
        object.position.set(p[0], p[1], p[2]);
        const k = frame * this.layout.frameSize + this.layout.offsets[index] + 3;
        const q = this.poses;
        object.quaternion.set(q[k + 1], q[k + 2], q[k + 3], q[k]).normalize();
      }
      const fill = (ids, geometry) => {
        const a = geometry.attributes.position.array;
        ids.forEach((id, n) => {
          this.position(frame, id, p);
          a[3 * n] = p[0];
          a[3 * n + 1] = p[1];
          a[3 * n + 2] = p[2];
        });
        geometry.attributes.position.needsUpdate = true;
        geometry.computeBoundingSphere();
      };
      if (this.surface) {
        fill(this.surface.ids, this.surface.geometry);
        this.surface.geometry.computeVertexNormals();
      }
      for (const strand of this.strands) fill(strand.ids, strand.geometry);
    }
  }

  // Where to look: the box of the bodies at the first frame and of the
  // static shapes other than planes.
  function frameCenter(view, statics) {
    const box = new THREE.Box3();
    const p = [0, 0, 0];
    const bodies = view.layout.offsets.length;
    for (let i = 0; i < bodies; i++) box.expandByPoint(new THREE.Vector3(...view.position(0, i, p)));
    for (const s of statics) {
      if (!s.position) continue;
      const reach = s.radius || (s.size ? Math.max(...s.size) / 2 : 0);
      box.expandByPoint(new THREE.Vector3(...s.position).addScalar(reach));
      box.expandByPoint(new THREE.Vector3(...s.position).addScalar(-reach));
    }
    const center = box.getCenter(new THREE.Vector3());
    const radius = Math.max(0.5, box.getSize(new THREE.Vector3()).length() * 0.5);
    return { center, radius };
  }

  function buildPlayer(root) {
    const sceneSelect = root.querySelector("#replay-scene");
    const leftSelect = root.querySelector("#replay-left");
    const rightSelect = root.querySelector("#replay-right");
    const playButton = root.querySelector("#replay-play");
    const slider = root.querySelector("#replay-frame");
    const label = root.querySelector("#replay-time");
    const canvas = root.querySelector("#replay-canvas");
    const captions = [root.querySelector("#replay-left-caption"), root.querySelector("#replay-right-caption")];
    const renderer = new THREE.WebGLRenderer({ canvas, antialias: true });
    renderer.setScissorTest(true);
    const camera = new THREE.PerspectiveCamera(40, 1, 0.01, 1000);
    camera.up.set(0, 0, 1);
    const orbit = { azimuth: -1.2, elevation: 0.45, distance: 3, center: new THREE.Vector3() };
    const state = { entry: null, sceneData: null, views: [null, null], frame: 0, playing: false, last: 0 };

    for (const entry of index) sceneSelect.add(new Option(entry.scene, entry.scene));

    function placeCamera() {
      const c = Math.cos(orbit.elevation);
      camera.position.set(
        orbit.center.x + orbit.distance * c * Math.cos(orbit.azimuth),
        orbit.center.y + orbit.distance * c * Math.sin(orbit.azimuth),
        orbit.center.z + orbit.distance * Math.sin(orbit.elevation));
      camera.lookAt(orbit.center);
    }

    function frames() {
      return Math.max(...state.views.filter(Boolean).map((v) => v.frames), 1);
    }

    function render() {
      const width = canvas.clientWidth, height = canvas.clientHeight;
      if (canvas.width !== width || canvas.height !== height) renderer.setSize(width, height, false);
      camera.aspect = width / 2 / height;
      camera.updateProjectionMatrix();
      placeCamera();
      state.views.forEach((view, side) => {
        renderer.setViewport(side * width / 2, 0, width / 2, height);
        renderer.setScissor(side * width / 2, 0, width / 2, height);
        if (!view) {
          renderer.setClearColor(BACKGROUND);
          renderer.clear();
          return;
        }
        view.setFrame(state.frame);
        renderer.render(view.three, camera);
      });
      const seconds = state.sceneData ? state.frame * state.sceneData.frameSeconds : 0;
      label.textContent = "frame " + state.frame + " of " + (frames() - 1) + ", t = " + seconds.toFixed(2) + " s";
      slider.value = state.frame;
    }

    function runNamed(name) {
      return state.sceneData.runs.find((r) => r.stepper === name);
    }

    function setSide(side, name) {
      const run = runNamed(name);
      const colors = [0x4a78b5, 0xc0563b];
      state.views[side] = run ? new RunView(state.sceneData, run, colors[side]) : null;
      captions[side].textContent = run ? name + (run.note ? " (" + run.note + ")" : "") : "";
      slider.max = frames() - 1;
    }

    function showScene(name, done) {
      const entry = index.find((e) => e.scene === name);
      if (!entry) return done && done();
      sceneSelect.value = name;
      loadScene(entry, (sceneData) => {
        try {
          show(entry, sceneData);
        } catch (e) {
          errors.push(entry.scene + ": " + (e && e.stack ? e.stack : String(e)));
          state.views = [null, null];
        }
        if (done) done();
      });
    }

    function show(entry, sceneData) {
      state.entry = entry;
      state.sceneData = sceneData;
      state.frame = 0;
      for (const select of [leftSelect, rightSelect]) {
        select.innerHTML = "";
        for (const run of sceneData ? sceneData.runs : []) select.add(new Option(run.stepper, run.stepper));
      }
      if (sceneData && sceneData.runs.length) {
        leftSelect.value = entry.left || sceneData.runs[0].stepper;
        rightSelect.value = entry.right || sceneData.runs[Math.min(1, sceneData.runs.length - 1)].stepper;
        setSide(0, leftSelect.value);
        setSide(1, rightSelect.value);
        const { center, radius } = frameCenter(state.views[0], sceneData.scene.static || []);
        orbit.center.copy(center);
        orbit.distance = radius * 4;
      } else {
        state.views = [null, null];
      }
      render();
    }

    sceneSelect.addEventListener("change", () => showScene(sceneSelect.value));
    leftSelect.addEventListener("change", () => { setSide(0, leftSelect.value); render(); });
    rightSelect.addEventListener("change", () => { setSide(1, rightSelect.value); render(); });
    slider.addEventListener("input", () => { state.frame = Number(slider.value); render(); });
    playButton.addEventListener("click", () => {
      state.playing = !state.playing;
      playButton.textContent = state.playing ? "pause" : "play";
      if (state.playing) {
        if (state.frame >= frames() - 1) state.frame = 0;
        state.last = performance.now();
        requestAnimationFrame(tick);
      }
    });
    function tick(now) {
      if (!state.playing || !state.sceneData) return;
      const step = state.sceneData.frameSeconds * 1000;
      while (now - state.last >= step) {
        state.last += step;
        state.frame++;
      }
      if (state.frame >= frames() - 1) {
        state.frame = frames() - 1;
        state.playing = false;
        playButton.textContent = "play";
      }
      render();
      if (state.playing) requestAnimationFrame(tick);
    }
    // Drag turns the camera about the scene, the wheel moves it nearer.
    let drag = null;
    canvas.addEventListener("pointerdown", (e) => { drag = { x: e.clientX, y: e.clientY }; });
    window.addEventListener("pointerup", () => { drag = null; });
    window.addEventListener("pointermove", (e) => {
      if (!drag) return;
      orbit.azimuth -= (e.clientX - drag.x) * 0.01;
      orbit.elevation = Math.max(-1.5, Math.min(1.5, orbit.elevation + (e.clientY - drag.y) * 0.01));
      drag = { x: e.clientX, y: e.clientY };
      render();
    });
    canvas.addEventListener("wheel", (e) => {
      e.preventDefault();
      orbit.distance *= Math.exp(e.deltaY * 0.001);
      render();
    }, { passive: false });
    window.addEventListener("resize", render);

    // Pixels on each half that differ from the background, read right
    // after drawing (the drawing buffer is not kept past the task).
    function drawnPixels() {
      const gl = renderer.getContext();
      const width = canvas.width, height = canvas.height;
      const pixels = new Uint8Array(width * height * 4);
      gl.readPixels(0, 0, width, height, gl.RGBA, gl.UNSIGNED_BYTE, pixels);
      const bg = new THREE.Color(BACKGROUND);
      const ref = [bg.r * 255, bg.g * 255, bg.b * 255];
      const counts = [0, 0];
      for (let y = 0; y < height; y++)
        for (let x = 0; x < width; x++) {
          const k = 4 * (y * width + x);
          if (Math.abs(pixels[k] - ref[0]) + Math.abs(pixels[k + 1] - ref[1]) + Math.abs(pixels[k + 2] - ref[2]) > 24)
            counts[x < width / 2 ? 0 : 1]++;
        }
      return counts;
    }

    function selftest() {
      const found = { scenes: [], errors };
      let k = 0;
      const next = () => {
        if (k >= index.length) {
          found.ok = errors.length === 0 && found.scenes.every((s) => s.drawn.every((d) => d.every((n) => n > 200)));
          const out = document.getElementById("selftest");
          out.textContent = JSON.stringify(found);
          document.title = "selftest done";
          return;
        }
        const entry = index[k++];
        showScene(entry.scene, () => {
          const listed = Array.from(leftSelect.options).map((o) => o.value);
          if (!state.views[0] || !state.views[1]) {
            found.scenes.push({ scene: entry.scene, listed, drawn: [[0, 0]], frames: 0 });
            setTimeout(next, 0);
            return;
          }
          const drawn = [];
          state.frame = 0;
          render();
          drawn.push(drawnPixels());
          state.frame = frames() - 1;
          render();
          drawn.push(drawnPixels());
          found.scenes.push({ scene: entry.scene, listed, drawn, frames: frames() });
          setTimeout(next, 0);
        });
      };
      next();
    }

    // report.html#scene=hair&frame=100 opens on that scene and frame.
    const wanted = new URLSearchParams(location.hash.slice(1));
    const first = index.find((e) => e.scene === wanted.get("scene")) || index[0];
    if (index.length) showScene(first.scene, () => {
      if (wanted.has("frame")) {
        state.frame = Math.max(0, Math.min(frames() - 1, Number(wanted.get("frame")) || 0));
        render();
      }
      if (/[?&]selftest/.test(location.search)) selftest();
    });
    else if (/[?&]selftest/.test(location.search)) {
      document.getElementById("selftest").textContent = JSON.stringify({ scenes: [], errors, ok: false });
      document.title = "selftest done";
    }
  }

  window.addEventListener("load", () => {
    const root = document.getElementById("replay");
    if (!root) return;
    if (typeof THREE === "undefined") {
      errors.push("three.min.js did not load");
      root.querySelector("#replay-time").textContent = "three.min.js is missing: the replay cannot draw";
      return;
    }
    buildPlayer(root);
  });
})();
