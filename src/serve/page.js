"use strict";
// The page of `matedit serve`: upload a photo, follow its decomposition (server-sent
// events), pick a material (a preset or another photo's), and edit with light sliders.

const $ = (id) => document.getElementById(id);
const STAGE_W = 760, STAGE_H = 440;   // the before/after box the photo is fitted into

const state = {
  info: null,
  photo: null,          // {id, width, height, report} once decomposed
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

// POST a file; resolves to {id, width, height}
async function upload(file) {
  const max = state.info && state.info.max_upload_bytes;
  if (max && file.size > max) throw new Error(`${file.name} is ${mb(file.size)}; the limit is ${mb(max)}.`);
  // header values must be ISO-8859-1: escape other names (the extension stays readable)
  const name = /^[\x20-\x7e]*$/.test(file.name) ? file.name : encodeURIComponent(file.name);
  const res = await api("/api/photos", { method: "POST", body: file, headers: { "X-Filename": name } });
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
const SPANS = { queued: [0, 0.02], mask: [0.02, 0.12], predict: [0.12, 0.2], refine: [0.2, 0.95], normals: [0.95, 1] };

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

async function openPhoto(file) {
  const gen = ++state.uploadGen;
  showError("");
  state.photo = null;
  document.body.dataset.photo = "";
  resetEditor();
  $("decomp").hidden = true;
  $("editor").hidden = true;
  document.body.dataset.state = "working";
  $("file").disabled = true;
  $("progress-box").hidden = false;
  showProgress({ message: `Uploading ${file.name}…` });
  try {
    const photo = await upload(file);
    showProgress({ stage: "queued", message: "Waiting for the server…" });
    const report = await follow(photo.id, (p) => gen === state.uploadGen && showProgress(p));
    if (gen !== state.uploadGen) return;
    state.photo = { ...photo, report };
    showDecomposition();
    document.body.dataset.state = "ready";
    showProgress({ done: 1, total: 1, message: `Ready: ${photo.width} × ${photo.height}.` });
    if (state.material) requestFull();
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
  const s = Math.min(STAGE_W / width, STAGE_H / height);
  $("stage").style.width = `${Math.round(width * s)}px`;
  $("stage").style.height = `${Math.round(height * s)}px`;
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
  gallery.replaceChildren(...presets.map((name) => {
    const b = document.createElement("button");
    b.className = "preset";
    b.type = "button";
    b.dataset.preset = name;
    b.title = name;
    const img = document.createElement("img");
    img.loading = "lazy";
    img.alt = "";
    img.src = presetUrl(name, "sphere.png");
    const span = document.createElement("span");
    span.textContent = name;
    b.append(img, span);
    return b;
  }));
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
