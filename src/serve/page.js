"use strict";
// The page of `matedit serve`: upload a photo, point at its object (a box and points,
// the mask cut out by the server drawn over the photo), follow its decomposition
// (server-sent events), pick a material (a preset or another photo's), and edit with
// light sliders.

const $ = (id) => document.getElementById(id);
const STAGE_W = 760, STAGE_H = 440;   // the before/after box the photo is fitted into

const state = {
  info: null,
  photo: null,          // {id, width, height, report} once decomposed
  held: null,           // {id, width, height, name}: uploaded, waiting to be pointed at
  prompt: { box: null, point: [], not: [] },   // in the photo's pixels
  history: [],          // what Undo takes back: "box", "point" or "not"
  segment: { busy: false, again: false, seq: 0 },   // at most one mask cut in flight
  maskImage: null,      // the last mask cut out (an <img> of the photo's size)
  material: null,       // the request's material part: {material: NAME} or {like: ID}
  uploadGen: 0,         // bumps per main upload: events of older uploads are ignored
  likeGen: 0,           // the same for the "material from another photo" upload
  fullSeq: 0,           // bumps per full edit request: only the latest one is shown
  inputSeq: 0,          // bumps per slider move: a full edit sent before it is stale
  preview: { busy: false, again: false },   // at most one preview in flight
  shownUrl: null,       // blob URL in #edit
  fullUrl: null,        // blob URL of the last full edit (the download)
};

// ---------- helpers

function showError(msg) {
  $("error").textContent = msg || "";
  $("error").hidden = !msg;
}

const photoUrl = (id, file) => `/api/photos/${encodeURIComponent(id)}/${file}`;
const presetUrl = (name, file) => `/api/presets/${encodeURIComponent(name)}/${file}`;
const mb = (n) => `${(n / 1048576).toFixed(n < 10485760 ? 1 : 0)} MB`;

// fetch that throws an Error with the server's one-line message on a 4xx/5xx
async function api(url, opts) {
  let res;
  try {
    res = await fetch(url, opts);
  } catch (e) {
    throw new Error(`Could not reach the server (${e.message}).`);
  }
  if (res.ok) return res;
  let msg = "";
  try {
    const text = await res.text();
    try { msg = JSON.parse(text).error || ""; } catch { msg = text.length < 200 ? text.trim() : ""; }
  } catch { /* no body */ }
  if (res.status === 413 && !/large|limit|big/i.test(msg)) {
    msg = "The file is too large" + (state.info ? ` (the limit is ${mb(state.info.max_upload_bytes)})` : "") + ".";
  }
  throw new Error(msg || `The server answered ${res.status} ${res.statusText}.`);
}

// POST a file (query: "?hold=1" to point at it first); resolves to {id, width, height}
async function upload(file, query = "") {
  const max = state.info && state.info.max_upload_bytes;
  if (max && file.size > max) throw new Error(`${file.name} is ${mb(file.size)}; the limit is ${mb(max)}.`);
  // header values must be ISO-8859-1: escape other names (the extension stays readable)
  const name = /^[\x20-\x7e]*$/.test(file.name) ? file.name : encodeURIComponent(file.name);
  const res = await api(`/api/photos${query}`, { method: "POST", body: file, headers: { "X-Filename": name } });
  return res.json();
}

// follow a photo's events; resolves to its report, rejects with the failure
function follow(id, onProgress) {
  return new Promise((resolve, reject) => {
    const es = new EventSource(photoUrl(id, "events"));
    const data = (e) => { try { return JSON.parse(e.data); } catch { return {}; } };
    let errors = 0;
    const end = (fn, value) => { es.close(); fn(value); };
    es.addEventListener("progress", (e) => { errors = 0; onProgress(data(e)); });
    es.addEventListener("ready", (e) => end(resolve, data(e)));
    es.addEventListener("failed", (e) =>
      end(reject, new Error(data(e).error || "The photo could not be decomposed.")));
    // the browser reconnects by itself; give up when it cannot, or after several tries
    es.onerror = () => {
      console.warn(`matedit: the event stream of ${id} broke (state ${es.readyState}, ${errors + 1} in a row)`);
      if (es.readyState === EventSource.CLOSED || ++errors >= 5) {
        end(reject, new Error("Lost the connection to the server while the photo was processed."));
      }
    };
  });
}

// each stage's share of the progress bar
const SPANS = { queued: [0, 0.02], segment: [0.02, 0.12], mask: [0.02, 0.12], predict: [0.12, 0.2], refine: [0.2, 0.95], normals: [0.95, 1] };

function showProgress(p) {
  const bar = $("progress"), [a, b] = SPANS[p.stage] || [0, 1];
  if (p.total > 0) bar.value = a + (b - a) * Math.min(1, p.done / p.total);
  else if (p.stage) bar.value = a;
  else bar.removeAttribute("value");   // indeterminate (uploading)
  $("status").textContent = p.message || p.stage || "";
}

function setLink(a, href, name) {
  if (href) { a.href = href; a.removeAttribute("aria-disabled"); }
  else { a.removeAttribute("href"); a.setAttribute("aria-disabled", "true"); }
  if (name) a.download = name;
}

// ---------- the main photo

// the server's messages name the command line's flags: the page's words instead
function forPage(msg) {
  return msg.replace(/: give --box or --mask\.?$/, ": drag a box around the object on the photo (click on it to add points), then press Analyse again.")
    .replace(/give --point on it or --mask/, "click on it");
}

// a photo fitted into the stage box, keeping its aspect: [width, height, scale]
function fitted(width, height) {
  const s = Math.min(STAGE_W / width, STAGE_H / height);
  return [Math.round(width * s), Math.round(height * s), s];
}

async function openPhoto(file) {
  const gen = ++state.uploadGen;
  showError("");
  state.photo = null;
  state.held = null;
  document.body.dataset.photo = "";
  resetEditor();
  $("decomp").hidden = true;
  $("editor").hidden = true;
  $("pointer").hidden = true;
  document.body.dataset.state = "working";
  $("file").disabled = true;
  $("progress-box").hidden = false;
  showProgress({ message: `Uploading ${file.name}…` });
  try {
    const photo = await upload(file, "?hold=1");
    if (gen !== state.uploadGen) return;
    state.held = { ...photo, name: file.name };
    showPointer();
    document.body.dataset.state = "pointing";
    showProgress({ done: 0, total: 1, message: `${photo.width} × ${photo.height}: point at the object, then Analyse.` });
  } catch (e) {
    if (gen !== state.uploadGen) return;
    document.body.dataset.state = "failed";
    showError(e.message);
    $("status").textContent = "Failed.";
    $("progress").value = 0;
  } finally {
    if (gen === state.uploadGen) { $("file").disabled = false; $("file").value = ""; }
  }
}

// decompose the held photo with the prompt (if any); on failure it can be pointed at again
async function analyse() {
  const held = state.held;
  if (!held) return;
  const gen = state.uploadGen;
  showError("");
  document.body.dataset.state = "working";
  showProgress({ stage: "queued", message: "Waiting for the server…" });
  try {
    await api(photoUrl(held.id, "analyse"),
      { method: "POST", headers: { "Content-Type": "application/json" }, body: JSON.stringify(promptBody()) });
    const report = await follow(held.id, (p) => gen === state.uploadGen && showProgress(p));
    if (gen !== state.uploadGen) return;
    state.photo = { id: held.id, width: held.width, height: held.height, report };
    state.held = null;
    $("pointer").hidden = true;
    showDecomposition();
    document.body.dataset.state = "ready";
    showProgress({ done: 1, total: 1, message: `Ready: ${held.width} × ${held.height}.` });
    if (state.material) requestFull();
  } catch (e) {
    if (gen !== state.uploadGen) return;
    document.body.dataset.state = "pointing";
    showError(forPage(e.message));
    $("status").textContent = "Not analysed: point at the object and try again.";
    $("progress").value = 0;
  }
}

// ---------- pointing at the object

function promptBody() {
  const p = state.prompt, body = {};
  if (p.box) body.box = p.box;
  if (p.point.length) body.point = p.point;
  if (p.not.length) body.not = p.not;
  return body;
}

function showPointer() {
  const { id, width, height } = state.held;
  const [w, h] = fitted(width, height);
  const stage = $("point-stage"), canvas = $("point-canvas");
  stage.style.width = `${w}px`;
  stage.style.height = `${h}px`;
  const dpr = window.devicePixelRatio || 1;
  canvas.width = Math.round(w * dpr);
  canvas.height = Math.round(h * dpr);
  $("point-photo").src = photoUrl(id, "photo.png");
  state.prompt = { box: null, point: [], not: [] };
  state.history = [];
  state.maskImage = null;
  state.segment.seq++;
  stage.dataset.mask = "none";
  $("pointer").hidden = false;
  drawPointer();
}

// the mask (tinted), the box and the points over the photo
function drawPointer(drag) {
  const canvas = $("point-canvas"), g = canvas.getContext("2d");
  if (!state.held) return;
  const k = canvas.width / state.held.width;   // canvas pixels per photo pixel
  g.clearRect(0, 0, canvas.width, canvas.height);
  if (state.maskImage) {
    // white on the object: kept where the mask is, tinted, half transparent
    const tint = document.createElement("canvas");
    tint.width = canvas.width;
    tint.height = canvas.height;
    const t = tint.getContext("2d");
    t.drawImage(state.maskImage, 0, 0, tint.width, tint.height);
    const d = t.getImageData(0, 0, tint.width, tint.height), px = d.data;
    for (let i = 0; i < px.length; i += 4) {
      const a = px[i];
      px[i] = 80; px[i + 1] = 170; px[i + 2] = 255; px[i + 3] = a * 0.5;
    }
    t.putImageData(d, 0, 0);
    g.drawImage(tint, 0, 0);
  }
  const dpr = window.devicePixelRatio || 1;
  const box = drag || state.prompt.box;
  if (box) {
    g.lineWidth = 2 * dpr;
    g.setLineDash([6 * dpr, 4 * dpr]);
    g.strokeStyle = "#e3aa4f";
    g.strokeRect(box[0] * k, box[1] * k, (box[2] - box[0]) * k, (box[3] - box[1]) * k);
    g.setLineDash([]);
  }
  for (const [list, colour] of [[state.prompt.point, "#4fd17a"], [state.prompt.not, "#e0605a"]]) {
    for (const [x, y] of list) {
      g.beginPath();
      g.arc((x + 0.5) * k, (y + 0.5) * k, 5 * dpr, 0, 2 * Math.PI);
      g.fillStyle = colour;
      g.fill();
      g.lineWidth = 1.5 * dpr;
      g.strokeStyle = "#000";
      g.stroke();
    }
  }
  const p = state.prompt;
  $("point-info").textContent = (p.box ? "box" : "no box") +
    ` · ${p.point.length} on · ${p.not.length} off`;
  $("analyse").textContent = p.box || p.point.length ? "Analyse the marked object" : "Analyse (find the object)";
}

// the photo pixel under a mouse event on the canvas
function photoPixel(e) {
  const r = $("point-canvas").getBoundingClientRect(), { width, height } = state.held;
  const x = Math.floor(((e.clientX - r.left) / r.width) * width);
  const y = Math.floor(((e.clientY - r.top) / r.height) * height);
  return [Math.min(width - 1, Math.max(0, x)), Math.min(height - 1, Math.max(0, y))];
}

// ask for the mask of the prompt; one in flight, the latest prompt next
async function requestSegment() {
  const sg = state.segment, held = state.held, stage = $("point-stage");
  if (!held) return;
  const p = state.prompt;
  if (!p.box && !p.point.length) {     // nothing to cut out from
    sg.seq++;
    state.maskImage = null;
    stage.dataset.mask = "none";
    drawPointer();
    return;
  }
  if (sg.busy) { sg.again = true; return; }
  sg.busy = true;
  sg.again = false;
  const seq = ++sg.seq;
  stage.dataset.mask = "pending";
  drawPointer();                        // the new box and points at once, the mask when cut
  try {
    const res = await api(photoUrl(held.id, "segment"),
      { method: "POST", headers: { "Content-Type": "application/json" }, body: JSON.stringify(promptBody()) });
    const pixels = res.headers.get("x-object-pixels");
    const img = new Image();
    img.src = URL.createObjectURL(await res.blob());
    try { await img.decode(); } finally { URL.revokeObjectURL(img.src); }
    if (seq === sg.seq && held === state.held) {
      state.maskImage = img;
      stage.dataset.mask = "shown";
      stage.dataset.pixels = pixels || "";
      showError("");
      drawPointer();
    }
  } catch (e) {
    if (seq === sg.seq && held === state.held) {
      state.maskImage = null;
      stage.dataset.mask = "error";
      showError(forPage(e.message));
      drawPointer();
    }
  } finally {
    sg.busy = false;
    if (sg.again) requestSegment();
  }
}

function wirePointer() {
  const canvas = $("point-canvas");
  let start = null;   // [photo pixel, client x, client y] of a press
  const dragged = (e) => start && Math.hypot(e.clientX - start[1], e.clientY - start[2]) > 4;
  const boxOf = (e) => {
    const [a, b] = [start[0], photoPixel(e)];
    return [Math.min(a[0], b[0]), Math.min(a[1], b[1]), Math.max(a[0], b[0]) + 1, Math.max(a[1], b[1]) + 1];
  };
  canvas.addEventListener("pointerdown", (e) => {
    if (!state.held || e.button !== 0) return;
    canvas.setPointerCapture(e.pointerId);
    start = [photoPixel(e), e.clientX, e.clientY];
  });
  canvas.addEventListener("pointermove", (e) => { if (dragged(e)) drawPointer(boxOf(e)); });
  canvas.addEventListener("pointerup", (e) => {
    if (!start) return;
    const p = state.prompt;
    if (dragged(e)) {
      p.box = boxOf(e);
      // points on the object outside the new box would be refused
      p.point = p.point.filter(([x, y]) => x >= p.box[0] && x < p.box[2] && y >= p.box[1] && y < p.box[3]);
      state.history = state.history.filter((h) => h !== "box");
      state.history.push("box");
    } else {
      const kind = e.shiftKey || $("point-not").checked ? "not" : "point";
      p[kind].push(start[0]);
      state.history.push(kind);
    }
    start = null;
    requestSegment();
  });
  canvas.addEventListener("pointercancel", () => { start = null; drawPointer(); });
  $("point-undo").addEventListener("click", () => {
    const p = state.prompt;
    // the last action's item, skipping what a new box already dropped
    while (state.history.length) {
      const h = state.history.pop();
      if (h === "box") { p.box = null; break; }
      if (p[h].length) { p[h].pop(); break; }
    }
    requestSegment();
  });
  $("point-clear").addEventListener("click", () => {
    state.prompt = { box: null, point: [], not: [] };
    state.history = [];
    showError("");
    requestSegment();
  });
  $("analyse").addEventListener("click", analyse);
}

function showDecomposition() {
  const { id, width, height, report } = state.photo;
  document.body.dataset.photo = id;
  for (const f of ["photo", "mask", "normals", "light", "sphere"]) $(`d-${f}`).src = photoUrl(id, `${f}.png`);
  for (const f of ["mask.png", "normals.png", "light.exr", "material.json", "report.json"]) {
    $(`dl-${f.split(".")[0]}`).href = photoUrl(id, f);
  }
  const db = (x) => (typeof x === "number" ? `${x.toFixed(2)} dB` : "?");
  const secs = Object.values(report.seconds || {}).filter((x) => typeof x === "number");
  $("report").textContent = `I′ PSNR ${db(report.psnr_predicted_db)} predicted → ${db(report.psnr_refined_db)} refined` +
    ` · ${report.object_pixels ?? "?"} object pixels` + (secs.length ? ` · ${Math.max(...secs).toFixed(1)} s` : "");
  // fit the photo into the stage box, keeping its aspect
  const [w, h] = fitted(width, height);
  $("stage").style.width = `${w}px`;
  $("stage").style.height = `${h}px`;
  $("before").src = photoUrl(id, "photo.png");
  $("decomp").hidden = false;
  $("editor").hidden = false;
}

// ---------- edits

function resetEditor() {
  state.fullSeq++;                       // responses in flight are dropped
  state.preview.again = false;
  const img = $("edit");
  img.hidden = true;
  img.removeAttribute("src");
  img.dataset.state = "none";
  delete img.dataset.request;
  $("editor").classList.remove("has-edit");   // hides the wipe until an edit is shown
  $("hint").textContent = "Pick a material on the right";
  state.shownUrl = state.fullUrl = null;  // old blob URLs are released below
  releaseAll();
  setLink($("download-edit"), null);
}

const liveUrls = new Set();
function releaseAll() {
  for (const u of liveUrls) {
    if (u !== state.shownUrl && u !== state.fullUrl) { URL.revokeObjectURL(u); liveUrls.delete(u); }
  }
}

// put a PNG blob into #edit; resolves once decoded (false if overtaken meanwhile)
async function showBlob(blob) {
  const url = URL.createObjectURL(blob);
  liveUrls.add(url);
  state.shownUrl = url;
  const img = $("edit");
  img.src = url;
  img.hidden = false;
  $("editor").classList.add("has-edit");
  try { await img.decode(); } catch { /* shown anyway once loaded */ }
  releaseAll();
  return state.shownUrl === url;
}

function editBody(preview) {
  return { ...state.material, turn: Number($("turn").value), exposure: Number($("exposure").value), preview };
}

async function postEdit(text) {
  const res = await api(photoUrl(state.photo.id, "edit"),
    { method: "POST", headers: { "Content-Type": "application/json" }, body: text });
  return res.blob();
}

// the full-resolution edit of the current material and sliders
async function requestFull() {
  if (!state.photo || !state.material) return;
  const seq = ++state.fullSeq, inputs = state.inputSeq;
  const text = JSON.stringify(editBody(false));
  const img = $("edit");
  img.dataset.state = "pending";
  $("hint").textContent = "Rendering…";   // seen until the first edit arrives
  try {
    const blob = await postEdit(text);
    if (seq !== state.fullSeq || inputs !== state.inputSeq) return;   // overtaken
    if (!(await showBlob(blob)) || seq !== state.fullSeq) return;
    state.fullUrl = state.shownUrl;
    releaseAll();
    setLink($("download-edit"), state.fullUrl);
    img.dataset.request = text;
    img.dataset.state = "done";
  } catch (e) {
    if (seq !== state.fullSeq) return;
    img.dataset.state = "error";
    $("hint").textContent = "Pick a material on the right";
    showError(`The edit failed: ${e.message}`);
  }
}

// a small preview while a slider is dragged; one in flight, the latest values next
async function requestPreview() {
  const p = state.preview;
  if (!state.photo || !state.material) return;
  if (p.busy) { p.again = true; return; }
  p.busy = true;
  p.again = false;
  const fulls = state.fullSeq;
  try {
    const blob = await postEdit(JSON.stringify(editBody(true)));
    // a full edit asked for since then wins
    if (fulls === state.fullSeq && (await showBlob(blob)) && fulls === state.fullSeq) {
      $("edit").dataset.state = "preview";
    }
  } catch (e) {
    showError(`The preview failed: ${e.message}`);
  } finally {
    p.busy = false;
    if (p.again) requestPreview();
  }
}

// ---------- materials

function selectMaterial(material, label, sphereUrl, jsonUrl, jsonName) {
  state.material = material;
  showError("");
  for (const b of document.querySelectorAll(".preset.selected")) b.classList.remove("selected");
  if (material.material) {
    const b = document.querySelector(`.preset[data-preset="${CSS.escape(material.material)}"]`);
    if (b) b.classList.add("selected");
  }
  $("swatch").src = sphereUrl;
  $("swatch").hidden = false;
  $("selected-name").textContent = label;
  setLink($("download-material"), jsonUrl, jsonName);
  requestFull();
}

function selectPreset(name) {
  selectMaterial({ material: name }, name, presetUrl(name, "sphere.png"),
    presetUrl(name, "material.json"), `${name}.json`);
}

function buildGallery(presets) {
  const gallery = $("gallery");
  const spheres = [];
  gallery.replaceChildren(...presets.map((name) => {
    const b = document.createElement("button");
    b.className = "preset";
    b.type = "button";
    b.dataset.preset = name;
    b.title = name;
    const img = document.createElement("img");
    img.alt = "";
    img.dataset.src = presetUrl(name, "sphere.png");
    spheres.push(img);
    const span = document.createElement("span");
    span.textContent = name;
    b.append(img, span);
    return b;
  }));
  loadInTurn(spheres);
}

// Pictures one after another: the server renders each sphere on first request, and all
// at once they held the browser's six connections to it, so that a photo's own requests
// waited behind the gallery.
function loadInTurn(imgs) {
  let i = 0;
  const next = () => {
    if (i >= imgs.length) return;
    const img = imgs[i++];
    img.addEventListener("load", next, { once: true });
    img.addEventListener("error", next, { once: true });
    img.src = img.dataset.src;
  };
  next();
}

// "material from another photo": decompose it, then use its material
async function openLike(file) {
  const gen = ++state.likeGen;
  const input = $("like-file"), status = $("like-status");
  input.disabled = true;
  status.textContent = `Uploading ${file.name}…`;
  try {
    const photo = await upload(file);
    await follow(photo.id, (p) => gen === state.likeGen && (status.textContent = p.message || p.stage));
    if (gen !== state.likeGen) return;
    status.textContent = "";
    selectMaterial({ like: photo.id }, `from ${file.name}`, photoUrl(photo.id, "sphere.png"),
      photoUrl(photo.id, "material.json"), "material.json");
  } catch (e) {
    if (gen !== state.likeGen) return;
    status.textContent = "";
    showError(`The material photo failed: ${e.message}`);
  } finally {
    if (gen === state.likeGen) { input.disabled = false; input.value = ""; }
  }
}

// ---------- wiring

function wire() {
  wirePointer();
  $("error").addEventListener("click", () => showError(""));
  $("file").addEventListener("change", (e) => { if (e.target.files[0]) openPhoto(e.target.files[0]); });
  $("like-file").addEventListener("change", (e) => { if (e.target.files[0]) openLike(e.target.files[0]); });

  // drag and drop (a file dropped elsewhere must not navigate away)
  const drop = $("drop");
  for (const t of ["dragover", "drop"]) window.addEventListener(t, (e) => e.preventDefault());
  drop.addEventListener("dragover", () => drop.classList.add("over"));
  drop.addEventListener("dragleave", () => drop.classList.remove("over"));
  drop.addEventListener("drop", (e) => {
    drop.classList.remove("over");
    const f = e.dataTransfer.files[0];
    if (f && document.body.dataset.state !== "working") openPhoto(f);
  });

  $("gallery").addEventListener("click", (e) => {
    const b = e.target.closest(".preset");
    if (b) selectPreset(b.dataset.preset);
  });
  $("filter").addEventListener("input", (e) => {
    const q = e.target.value.trim().toLowerCase();
    for (const b of $("gallery").children) b.hidden = !b.dataset.preset.toLowerCase().includes(q);
  });

  // sliders: previews while dragging, the full edit on release
  const labels = { turn: (v) => `${v}°`, exposure: (v) => `${Number(v).toFixed(1)} EV` };
  for (const id of ["turn", "exposure"]) {
    const input = $(id);
    input.addEventListener("input", () => {
      $(`${id}-value`).textContent = labels[id](input.value);
      state.inputSeq++;
      requestPreview();
    });
    input.addEventListener("change", () => {
      state.preview.again = false;
      requestFull();
    });
  }

  // before/after wipe: the edit shows right of the line
  const wipe = () => {
    const v = $("wipe").value;
    $("edit").style.clipPath = `inset(0 0 0 ${v}%)`;
    $("wipe-line").style.left = `${v}%`;
  };
  $("wipe").addEventListener("input", wipe);
  wipe();
}

async function init() {
  wire();
  try {
    const res = await api("/api/info");
    state.info = await res.json();
    $("limits").textContent = `JPEG, PNG or EXR, up to ${mb(state.info.max_upload_bytes)}` +
      ` and ${(state.info.max_pixels / 1e6).toFixed(1)} Mpx`;
    buildGallery(state.info.presets || []);
  } catch (e) {
    showError(`Could not load the presets: ${e.message}`);
  }
}

init();
