// nlo_lab's 3-D view: meshcat's own three.js viewer inside a Jupyter widget (anywidget).
// The kernel sends meshcat's command messages (msgpack bytes, framed as uint32 length + bytes)
// over the widget's comm; viewer.handle_command_bytearray runs each, as meshcat's own page does.

const PREFIX = "IPY_MODEL_";
// What a test or a benchmark reads from the page: views, commands applied, frames drawn after an update.
const STATS = (globalThis.__nloLabView ??= { views: 0, messages: 0, commands: 0, bytes: 0, frames: [], arrivals: [], renderMs: [], draws: [] });
const keep = (list, value) => { list.push(value); if (list.length > 2000) list.splice(0, 1000); };

// meshcat's bundle is a UMD script that sets self.MeshCat. Evaluate it once per page, as a module
// (what anywidget itself does with a widget's code); `define` is hidden from it so that a
// require.js page (classic Notebook) does not capture it as an anonymous AMD module.
function loadMeshCat(code) {
  if (!globalThis.__nloLabMeshCat) {
    const source = "const define = undefined;\n" + code;
    const url = URL.createObjectURL(new Blob([source], { type: "text/javascript" }));
    globalThis.__nloLabMeshCat = import(url).then(() => {
      URL.revokeObjectURL(url);
      if (!globalThis.MeshCat) throw new Error("meshcat's bundle did not define MeshCat");
      return globalThis.MeshCat;
    });
  }
  return globalThis.__nloLabMeshCat;
}

// The WebGL renderer's name, and whether it draws on the CPU (SwiftShader, llvmpipe: a browser without a GPU,
// or with GPU access off; Windows' WARP is the "Basic Render Driver"). Asked once per page, from a throwaway context.
function webglRenderer() {
  if (!globalThis.__nloLabRenderer) {
    let name = "unknown";
    try {
      const canvas = document.createElement("canvas");
      const gl = canvas.getContext("webgl2") || canvas.getContext("webgl");
      const info = gl.getExtension("WEBGL_debug_renderer_info");
      name = String(gl.getParameter(info ? info.UNMASKED_RENDERER_WEBGL : gl.RENDERER));
      const lose = gl.getExtension("WEBGL_lose_context");
      if (lose) lose.loseContext();  // browsers allow only a few live contexts per page
    } catch (err) { /* no WebGL: the viewer's own error says so */ }
    globalThis.__nloLabRenderer = { name, software: /swiftshader|llvmpipe|softpipe|software|basic render/i.test(name) };
  }
  return globalThis.__nloLabRenderer;
}

function asBytes(buffer) {
  if (buffer instanceof Uint8Array) return buffer;
  if (ArrayBuffer.isView(buffer)) return new Uint8Array(buffer.buffer, buffer.byteOffset, buffer.byteLength);
  return new Uint8Array(buffer);
}

// Run every framed command of one buffer; returns how many ran.
function applyCommands(viewer, buffer) {
  const bytes = asBytes(buffer);
  const view = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
  let at = 0, count = 0;
  while (at + 4 <= bytes.length) {
    const n = view.getUint32(at, true);
    viewer.handle_command_bytearray(bytes.subarray(at + 4, at + 4 + n));
    at += 4 + n;
    count += 1;
  }
  return count;
}

async function render({ model, el }) {
  const id = `${Date.now().toString(36)}-${Math.random().toString(36).slice(2)}`;
  el.classList.add("nlo-lab-view");
  const box = document.createElement("div");
  box.style.cssText = "position: relative; width: 100%; overflow: hidden";
  const pane = document.createElement("div");
  pane.style.cssText = `width: 100%; height: ${model.get("height")}px`;
  const note = document.createElement("div");
  note.className = "nlo-lab-view-message";
  note.style.cssText = "position: absolute; left: 0; top: 0; right: 0; padding: 6px 10px; font: 13px sans-serif;" +
    "background: #fff3cd; color: #5c4400; border-bottom: 1px solid #e0c36a; display: none; z-index: 2";
  // Play / pause of the scene's animation (show_view and show_human loop theirs): shown while the scene has one.
  const play = document.createElement("button");
  play.className = "nlo-lab-play";
  play.type = "button";
  play.style.cssText = "position: absolute; left: 8px; bottom: 8px; z-index: 2; display: none; min-width: 30px;" +
    "padding: 2px 8px; font: 14px sans-serif; background: rgba(255,255,255,0.85); border: 1px solid #999; border-radius: 4px; cursor: pointer";
  box.append(pane, note, play);
  el.append(box);
  let status = "loading the 3-D viewer ...";
  const show = () => {
    const text = model.get("message") || status;
    note.textContent = text;
    note.style.display = text ? "block" : "none";
  };
  const setStatus = (text) => { status = text; show(); };
  model.on("change:message", show);
  show();

  let viewer;
  try {
    const ref = model.get("_bundle");
    const bundle = await model.widget_manager.get_model(String(ref).slice(PREFIX.length));
    const MeshCat = await loadMeshCat(bundle.get("code"));
    // meshcat's own renderer (multisampled, soft shadows), except that multisampling is off where WebGL draws on
    // the CPU: there it costs about a third of the frame rate (docs/RESULTS.md); the widget's antialias overrides.
    const renderer = webglRenderer();
    const wanted = model.get("antialias");
    const antialias = wanted === null || wanted === undefined ? !renderer.software : Boolean(wanted);
    const three = new MeshCat.THREE.WebGLRenderer({ antialias, alpha: true });
    three.shadowMap.enabled = true;
    three.shadowMap.type = MeshCat.THREE.PCFSoftShadowMap;
    pane.appendChild(three.domElement);
    // what this view draws with, for a reader of the page (tests, benchmarks): the context's own answer
    three.domElement.dataset.renderer = renderer.name;
    three.domElement.dataset.antialias = String(Boolean(three.getContext().getContextAttributes().antialias));
    viewer = new MeshCat.Viewer(pane, false, three);  // false: we run the drawing loop (and stop it)
  } catch (err) {
    setStatus(`The 3-D view could not start: ${err && err.message ? err.message : err}`);
    return;
  }
  // meshcat sizes its canvas to the window's height on window resizes: size it to the pane instead.
  const setSize = viewer.set_3d_pane_size.bind(viewer);
  viewer.set_3d_pane_size = (w, h) => setSize(w ?? pane.clientWidth, h ?? pane.clientHeight);
  STATS.views += 1;
  setStatus("");  // the viewer runs; a missing answer from the kernel is said below, after 8 s

  let version = -1, updated = false, alive = true, answered = false, waiting, retry;
  const run = (buffer) => {
    const n = applyCommands(viewer, buffer);
    STATS.commands += n;
    STATS.bytes += asBytes(buffer).byteLength;
    updated = true;
    return n;
  };
  // The scene kept in the widget's state: drawn at start, and again whenever the kernel stores a newer one
  // (after the cell that showed this view, even while the kernel is busy with the next cells).
  const drawSaved = () => {
    try {
      const scene = model.get("_scene");
      const saved = model.get("_scene_version");
      if (scene && scene.byteLength && saved > version) {
        run(scene);
        version = saved;
      }
    } catch (err) {
      setStatus(`The saved scene could not be drawn: ${err.message || err}`);
    }
  };
  drawSaved();
  const onSaved = () => {  // a kernel stored it just now: it is alive (busy, maybe), not gone
    clearTimeout(waiting);
    setStatus("");
    drawSaved();
  };
  model.on("change:_scene_version", onSaved);

  const onMessage = (msg, buffers) => {
    if (!msg || !alive) return;
    try {
      if (msg.type === "commands" && msg.version > version) {
        STATS.messages += 1;
        keep(STATS.arrivals, performance.now());
        run(buffers[0]);
        version = msg.version;
      } else if ((msg.type === "scene" || msg.type === "current") && msg.view === id && !answered) {
        if (msg.type === "scene" && msg.version > version) run(buffers[0]);  // not again what the view has
        version = Math.max(version, msg.version);
        answered = true;
        clearTimeout(waiting);
        clearTimeout(retry);
        setStatus("");
      }
    } catch (err) {
      setStatus(`A scene update failed: ${err.message || err}`);
    }
  };
  model.on("msg:custom", onMessage);
  // Ask the kernel for whatever changed since the saved scene, and ask again (1, 2, 4 ... 30 s apart) until it
  // answers: a kernel busy with the next cells answers late, a message lost on the way is sent again.
  // No answer after 8 s: say so over the view (the saved scene, if any, stays drawn).
  waiting = setTimeout(() => setStatus(
    version >= 0 ? "No kernel answers (busy, or gone): this is the scene as it was saved. It turns live when the " +
                   "kernel answers; if it never does, run the cell again."
                 : "No kernel answers (busy, or gone) and no saved scene: run the cell to draw it."), 8000);
  let pause = 1000;
  const ask = () => {
    if (!alive || answered) return;
    try {
      model.send({ type: "ready", view: id, version });
    } catch (err) {
      clearTimeout(waiting);
      setStatus(`The kernel is not connected (${err.message || err}): run the cell again.`);
      return;
    }
    retry = setTimeout(ask, pause);
    pause = Math.min(2 * pause, 30000);
  };
  ask();

  const loop = () => {
    if (!alive) return;
    requestAnimationFrame(loop);
    viewer.animator.update();
    showPlay();
    if (viewer.needs_render) {
      const t0 = performance.now();
      viewer.render();
      viewer.needs_render = false;
      const t1 = performance.now();
      keep(STATS.renderMs, t1 - t0);
      keep(STATS.draws, t1);
      if (updated) {
        keep(STATS.frames, t1);
        updated = false;
      }
    }
  };
  // The button follows the animator (the viewer's own controls and a new animation change it too).
  let shown = null;
  const showPlay = () => {
    const animator = viewer.animator;
    const state = animator.duration > 0 ? (animator.playing ? "playing" : "paused") : "none";
    if (state === shown) return;
    shown = state;
    play.style.display = state === "none" ? "none" : "block";
    play.textContent = state === "playing" ? "\u275A\u275A" : "\u25B6";
    const label = state === "playing" ? "Pause the animation" : "Play the animation";
    play.title = label;
    play.setAttribute("aria-label", label);
    play.dataset.state = state;
  };
  play.addEventListener("click", () => {
    if (viewer.animator.playing) viewer.animator.pause(); else viewer.animator.play();
    showPlay();
  });
  const resize = new ResizeObserver(() => viewer.set_3d_pane_size());
  resize.observe(pane);
  viewer.set_3d_pane_size();
  loop();

  return () => {
    alive = false;
    clearTimeout(waiting);
    clearTimeout(retry);
    model.off("change:_scene_version", onSaved);
    resize.disconnect();
    model.off("msg:custom", onMessage);
    model.off("change:message", show);
    STATS.views -= 1;
    try {
      viewer.renderer.dispose();
      viewer.renderer.forceContextLoss();  // browsers allow only a few live WebGL contexts per page
    } catch (err) { /* already gone */ }
  };
}

export default { render };
