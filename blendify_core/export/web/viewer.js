// blendify-core's offline scene viewer (this project's own code; three.js and its examples are inlined
// beside it, see SOURCES.md). The page holds everything: the libraries as text, the scene as a glTF binary
// written by blendify_core/export/gltf.py (in the IR's +Z-up axes) and a JSON description of the camera,
// its frustum and the lights. Nothing is fetched from the network.
const text = (id) => document.getElementById(id).textContent;
const status = document.getElementById("blendify-status");
const moduleUrl = (code) => URL.createObjectURL(new Blob([code], { type: "text/javascript" }));

try {
  const threeUrl = moduleUrl(text("lib-three"));
  const withThree = (code) => code.replace(/from\s*'three'/g, `from '${threeUrl}'`);
  const utilsUrl = moduleUrl(withThree(text("lib-geometry-utils")));
  const loaderUrl = moduleUrl(
    withThree(text("lib-gltf-loader")).replace("'../utils/BufferGeometryUtils.js'", `'${utilsUrl}'`),
  );
  const THREE = await import(threeUrl);
  const { GLTFLoader } = await import(loaderUrl);
  const { OrbitControls } = await import(moduleUrl(withThree(text("lib-orbit-controls"))));
  const { RoomEnvironment } = await import(moduleUrl(withThree(text("lib-room-environment"))));
  const data = JSON.parse(text("blendify-scene"));

  const renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
  renderer.setPixelRatio(window.devicePixelRatio || 1);
  document.getElementById("blendify-view").appendChild(renderer.domElement);
  const scene = new THREE.Scene();
  scene.background = new THREE.Color().setRGB(...data.background);
  scene.environment = new THREE.PMREMGenerator(renderer).fromScene(new RoomEnvironment(renderer), 0.04).texture;

  // the scene: the glTF binary, its punctual lights switched off (the view is lit by a neutral room and a
  // headlight: watts converted to candela light a viewer's exposure-free scene far too brightly)
  const bytes = Uint8Array.from(atob(text("blendify-glb")), (c) => c.charCodeAt(0));
  const gltf = await new Promise((resolve, reject) => new GLTFLoader().parse(bytes.buffer, "", resolve, reject));
  gltf.scene.traverse((o) => {
    if (o.isLight) o.visible = false;
    if (o.isPoints) {
      const size = o.geometry.userData.point_size;
      const old = o.material;
      o.material = new THREE.PointsMaterial({
        size: size || 0.01, // the diameter (the mean of per-point sizes)
        sizeAttenuation: true,
        vertexColors: old.vertexColors,
        color: old.color,
      });
    }
  });
  scene.add(gltf.scene);

  // helpers: the render camera's frustum and the lights (hidden with F)
  const helpers = new THREE.Group();
  const segments = new THREE.BufferGeometry();
  segments.setAttribute("position", new THREE.Float32BufferAttribute(data.frustum.flat(), 3));
  helpers.add(new THREE.LineSegments(segments, new THREE.LineBasicMaterial({ color: 0x30a0ff })));
  for (const light of data.lights) {
    const color = new THREE.Color().setRGB(...light.color);
    const marker = new THREE.Mesh(
      new THREE.OctahedronGeometry(data.marker_size),
      new THREE.MeshBasicMaterial({ color, wireframe: true }),
    );
    marker.position.set(...light.position);
    helpers.add(marker);
    if (light.direction) {
      const dir = new THREE.Vector3(...light.direction);
      helpers.add(new THREE.ArrowHelper(dir, marker.position, data.marker_size * 6, color.getHex()));
    }
    if (light.outline) {
      const g = new THREE.BufferGeometry().setFromPoints(light.outline.map((p) => new THREE.Vector3(...p)));
      helpers.add(new THREE.LineLoop(g, new THREE.LineBasicMaterial({ color })));
    }
  }
  helpers.visible = data.show_helpers;
  scene.add(helpers);

  // the render camera, with its exact intrinsics (principal point, fx != fy) as the projection
  const c = data.camera;
  let camera;
  if (c.type === "orthographic") {
    const s = c.ortho_scale / c.width;
    camera = new THREE.OrthographicCamera(
      -(c.cx + 0.5) * s, (c.width - c.cx - 0.5) * s, (c.cy + 0.5) * s, -(c.height - c.cy - 0.5) * s, c.near, c.far,
    );
  } else {
    camera = new THREE.PerspectiveCamera(50, c.width / c.height, c.near, c.far);
    const n = c.near;
    camera.projectionMatrix.makePerspective(
      (-(c.cx + 0.5) / c.fx) * n, ((c.width - c.cx - 0.5) / c.fx) * n,
      ((c.cy + 0.5) / c.fy) * n, (-(c.height - c.cy - 0.5) / c.fy) * n, n, c.far,
    );
    camera.projectionMatrixInverse.copy(camera.projectionMatrix).invert();
    camera.updateProjectionMatrix = () => {}; // keep the intrinsics
  }
  camera.up.set(0, 0, 1); // the IR's world is +Z up
  const home = new THREE.Matrix4().fromArray(c.matrix);
  const headlight = new THREE.DirectionalLight(0xffffff, 1.5);
  headlight.position.set(0, 0, 1);
  camera.add(headlight);
  scene.add(camera);
  const controls = new OrbitControls(camera, renderer.domElement);
  const render = () => renderer.render(scene, camera);
  const goHome = () => {
    home.decompose(camera.position, camera.quaternion, camera.scale);
    controls.target.copy(new THREE.Vector3(0, 0, -c.target_distance).applyMatrix4(home));
    camera.updateMatrixWorld();
    render();
  };
  controls.addEventListener("change", render);
  const fit = () => {
    const k = Math.min(window.innerWidth / c.width, window.innerHeight / c.height);
    renderer.setSize(Math.max(1, Math.round(c.width * k)), Math.max(1, Math.round(c.height * k)));
    render();
  };
  window.addEventListener("resize", fit);
  window.addEventListener("keydown", (e) => {
    if (e.key === "r" || e.key === "R") goHome();
    if (e.key === "f" || e.key === "F") {
      helpers.visible = !helpers.visible;
      render();
    }
    if (e.key === "h" || e.key === "H") {
      status.textContent = status.textContent === data.summary ? "H: help" : data.summary;
    }
  });
  goHome();
  fit();
  status.textContent = "H: help";
  document.body.dataset.ready = "1";
} catch (err) {
  status.hidden = false;
  status.textContent = `blendify viewer: ${err && err.message ? err.message : err}`;
  document.body.dataset.ready = "error";
}
