// nlo_lab's camera view (anywidget): the learner's camera, in the page, sends downscaled JPEG frames to the kernel
// over the widget's own comm, one at a time. Nothing is fetched from anywhere: no import, no URL, no port.
//
// Back-pressure: at most one frame is in flight. A camera frame that arrives while the kernel still works on the
// last one is dropped (counted, never queued); the next frame is taken when the kernel's answer ("done") comes.

// What a test or a benchmark reads from the page (all views of this page together).
// traits: the widget's figures as the page has them (synced from the kernel), of the view updated last.
const STATS = (globalThis.__nloLabLive ??= {
  views: 0, captured: 0, sent: 0, answered: 0, dropped: 0, found: 0, inFlight: 0, maxInFlight: 0, roundTripMs: [], messages: [],
  errors: [], traits: {},
});
const keep = (list, value) => { list.push(value); if (list.length > 500) list.splice(0, 250); };
const ACTIVE = (globalThis.__nloLabLiveActive ??= new Map());  // model id -> stop() of the view whose camera runs

// Why the camera cannot start, in words a learner can act on.
function cameraProblem(err) {
  const name = err && err.name ? err.name : "";
  if (name === "NotAllowedError" || name === "SecurityError" || name === "PermissionDeniedError") {
    return "Camera access was refused. Allow the camera for this page (the camera icon in the address bar, or the " +
      "browser's site settings), then press Start again.";
  }
  if (name === "NotFoundError" || name === "DevicesNotFoundError" || name === "OverconstrainedError") {
    return "No camera was found. Connect a camera (or turn it on in the system's privacy settings), then press Start again.";
  }
  if (name === "NotReadableError" || name === "TrackStartError" || name === "AbortError") {
    return "The camera could not start: another program may be using it. Close it, then press Start again.";
  }
  return `The camera could not start: ${name ? name + ": " : ""}${err && err.message ? err.message : err}`;
}

// The page itself cannot offer a camera: say why (browsers give getUserMedia to secure pages only).
function pageProblem() {
  if (!globalThis.isSecureContext) {
    const here = `${location.protocol}//${location.host}`;
    return `The camera needs a secure page: https, or http on localhost / 127.0.0.1. This page is ${here}, so the ` +
      "browser does not offer the camera. On JupyterHub or Binder, open the hub over https; for a kernel on another " +
      "machine, tunnel it (ssh -L 8888:localhost:8888 host) and open http://localhost:8888.";
  }
  if (!(navigator.mediaDevices && navigator.mediaDevices.getUserMedia)) {
    return "This browser offers no camera to web pages (navigator.mediaDevices.getUserMedia is missing).";
  }
  return "";
}

function render({ model, el }) {
  STATS.views += 1;
  el.classList.add("nlo-lab-camera");
  const root = document.createElement("div");
  root.style.cssText = "display: flex; flex-direction: column; gap: 4px; font: 13px sans-serif";
  const bar = document.createElement("div");
  bar.style.cssText = "display: flex; align-items: center; gap: 10px";
  const button = document.createElement("button");
  button.type = "button";
  button.className = "nlo-lab-camera-button jupyter-button";
  button.textContent = "Start";
  button.style.cssText = "min-width: 64px";
  const status = document.createElement("span");
  status.className = "nlo-lab-camera-status";
  bar.append(button, status);
  const stage = document.createElement("div");
  stage.style.cssText = "position: relative; background: #222; overflow: hidden";
  const video = document.createElement("video");
  video.muted = true;
  video.playsInline = true;
  video.autoplay = true;
  video.style.cssText = "display: block; width: 100%; height: 100%; object-fit: contain";
  const overlay = document.createElement("canvas");
  overlay.className = "nlo-lab-camera-overlay";
  overlay.style.cssText = "position: absolute; left: 0; top: 0; width: 100%; height: 100%; pointer-events: none";
  stage.append(video, overlay);
  const note = document.createElement("div");
  note.className = "nlo-lab-camera-message";
  note.style.cssText = "padding: 6px 10px; background: #fff3cd; color: #5c4400; border: 1px solid #e0c36a; display: none";
  root.append(bar, stage, note);
  el.append(root);

  const grab = document.createElement("canvas");  // the downscaled frame that is encoded
  let stream = null, running = false, inFlight = false, seq = 0, sentAt = 0, pollTimer = null, frameHandle = null;

  const size = () => {
    const h = model.get("height");
    stage.style.height = `${h}px`;
    stage.style.width = `${Math.round(h * 4 / 3)}px`;
    const mirror = model.get("mirror") ? "scaleX(-1)" : "none";
    video.style.transform = mirror;
    overlay.style.transform = mirror;
  };
  size();
  model.on("change:height", size);
  model.on("change:mirror", size);

  const say = (text) => {
    note.textContent = text;
    note.style.display = text ? "block" : "none";
  };
  const showStatus = () => {
    const parts = [];
    if (running) parts.push(inFlight && performance.now() - sentAt > 2000 ? "waiting for the kernel (busy with another cell?)" : "camera on");
    parts.push(`${model.get("frames_processed")} frames`, `${model.get("fps").toFixed(1)} fps`,
      `latency ${model.get("latency_ms").toFixed(0)} ms`);
    if (model.get("frames_processed") > 0) parts.push(model.get("found") ? "person seen" : "nobody seen");
    if (model.get("recording")) parts.push("recording");
    status.textContent = parts.join(" · ");
    STATS.traits = Object.fromEntries(["frames_received", "frames_processed", "frames_rejected", "fps", "latency_ms", "found", "error",
      "camera", "recording"].map((k) => [k, model.get(k)]));
  };
  for (const name of ["frames_processed", "fps", "latency_ms", "found", "recording"]) model.on(`change:${name}`, showStatus);
  const showError = () => { if (model.get("error")) say(model.get("error")); };
  model.on("change:error", showError);
  showStatus();

  const setCamera = (state, message) => {
    model.set("camera", state);
    model.set("camera_message", message || "");
    model.save_changes();
  };

  function drawPoints(points) {
    const w = stage.clientWidth, h = stage.clientHeight;
    overlay.width = w;
    overlay.height = h;
    const ctx = overlay.getContext("2d");
    ctx.clearRect(0, 0, w, h);
    if (!points || !points.length || !video.videoWidth) return;
    // the video is drawn "contain": find its box in the stage
    const scale = Math.min(w / video.videoWidth, h / video.videoHeight);
    const vw = video.videoWidth * scale, vh = video.videoHeight * scale, x0 = (w - vw) / 2, y0 = (h - vh) / 2;
    ctx.fillStyle = "#2ca02c";
    for (const [x, y] of points) {
      ctx.beginPath();
      ctx.arc(x0 + x * vw, y0 + y * vh, 3, 0, 2 * Math.PI);
      ctx.fill();
    }
  }

  // One camera frame: send it if nothing is in flight, else drop it.
  async function onFrame() {
    if (!running) return;
    STATS.captured += 1;
    if (inFlight) { STATS.dropped += 1; return; }
    const vw = video.videoWidth, vh = video.videoHeight;
    if (!vw || !vh) return;
    inFlight = true;
    STATS.inFlight += 1;
    STATS.maxInFlight = Math.max(STATS.maxInFlight, STATS.inFlight);
    try {
      const scale = Math.min(1, model.get("frame_size") / Math.max(vw, vh));
      grab.width = Math.max(1, Math.round(vw * scale));
      grab.height = Math.max(1, Math.round(vh * scale));
      grab.getContext("2d").drawImage(video, 0, 0, grab.width, grab.height);
      const t = performance.now() / 1000;  // the frame's time on the page's clock [s]
      const blob = await new Promise((resolve) => grab.toBlob(resolve, "image/jpeg", model.get("jpeg_quality")));
      if (!blob || !running) throw new Error("the browser did not encode the frame");
      const bytes = await blob.arrayBuffer();
      seq += 1;
      sentAt = performance.now();
      model.send({ type: "frame", seq, t }, undefined, [bytes]);
      STATS.sent += 1;
    } catch (err) {
      inFlight = false;
      STATS.inFlight -= 1;
      if (running) keep(STATS.errors, String(err && err.message ? err.message : err));
    }
  }

  function onAnswer(msg) {
    if (!msg || msg.type !== "done" || msg.seq !== seq) return;  // another view's frame, or the kernel's own (play_video)
    if (inFlight) {
      inFlight = false;
      STATS.inFlight -= 1;
      STATS.answered += 1;
      keep(STATS.roundTripMs, performance.now() - sentAt);
    }
    if (msg.found) STATS.found += 1;
    drawPoints(msg.points);
    if (msg.error) { keep(STATS.messages, msg.error); say(msg.error); }
    else if (note.textContent === model.get("error")) say("");
    showStatus();
  }
  model.on("msg:custom", onAnswer);

  // Each new camera frame: requestVideoFrameCallback where the browser has it, else polling the video's clock.
  function watchFrames() {
    if (video.requestVideoFrameCallback) {
      const next = () => { frameHandle = video.requestVideoFrameCallback(() => { onFrame(); if (running) next(); }); };
      next();
    } else {
      let last = -1;
      pollTimer = setInterval(() => { if (video.currentTime !== last) { last = video.currentTime; onFrame(); } }, 15);
    }
  }

  async function start() {
    const problem = pageProblem();
    if (problem) { say(problem); setCamera("failed", problem); return; }
    const other = ACTIVE.get(model.model_id ?? model);
    if (other) other();  // one camera per widget: another view of it stops
    button.disabled = true;
    setCamera("starting", "");
    say("");
    try {
      stream = await navigator.mediaDevices.getUserMedia({ video: { width: { ideal: 640 }, height: { ideal: 480 } }, audio: false });
    } catch (err) {
      const text = cameraProblem(err);
      say(text);
      setCamera("failed", text);
      button.disabled = false;
      return;
    }
    video.srcObject = stream;
    try { await video.play(); } catch (err) { /* autoplay of a muted video is allowed; frames come anyway */ }
    running = true;
    ACTIVE.set(model.model_id ?? model, stop);
    button.textContent = "Stop";
    button.disabled = false;
    setCamera("on", "");
    model.send({ type: "started" });
    watchFrames();
    showStatus();
  }

  function stop() {
    running = false;
    if (frameHandle !== null && video.cancelVideoFrameCallback) video.cancelVideoFrameCallback(frameHandle);
    frameHandle = null;
    if (pollTimer) clearInterval(pollTimer);
    pollTimer = null;
    if (stream) for (const track of stream.getTracks()) track.stop();
    stream = null;
    video.srcObject = null;
    if (ACTIVE.get(model.model_id ?? model) === stop) ACTIVE.delete(model.model_id ?? model);
    button.textContent = "Start";
    drawPoints([]);
    if (model.get("camera") !== "failed") setCamera("off", "");
    showStatus();
  }

  button.addEventListener("click", () => (running ? stop() : start()));
  const initial = pageProblem();
  if (initial) say(initial);
  return () => {  // the view is removed (cell cleared, page closed): the camera goes off
    if (running) stop();
    model.off("msg:custom", onAnswer);
  };
}

export default { render };
