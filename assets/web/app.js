// The page of `substep serve`: one session per tab, driven through the JSON API of
// docs/server.md; frames arrive as an MJPEG stream in the <img>, stats as server-sent events.
// The timeline scrubs the session's kept steps, the inspector shows the selected body there.
'use strict';

const $ = (id) => document.getElementById(id);
const S = {
  id: null, state: null, methods: null, settingByKey: {}, stats: null,
  events: null, cameraQueue: null, cameraBusy: false,
  timeline: null,      // first, last, shown, shown_step, live, recorded, dt [s]
  markers: [],         // GET timeline's markers
  selected: null,      // the selected body's name
  inspect: null,       // the inspector JSON shown
  shownStep: null,     // the step the inspector was asked for
  scrubWanted: null,   // the latest scrub body not yet sent
  scrubDragging: false,
};
const sleep = (ms) => new Promise((r) => setTimeout(r, ms));

// ---- requests ----

// body: an object (sent as JSON) or a Blob (sent as its bytes).
async function api(method, path, body) {
  const init = { method, headers: {} };
  if (body instanceof Blob) {
    init.body = body;
    init.headers['Content-Type'] = 'application/octet-stream';
  } else if (body !== undefined) {
    init.body = JSON.stringify(body);
    init.headers['Content-Type'] = 'application/json';
  }
  const res = await fetch(path, init);
  const text = await res.text();
  let data = null;
  try { data = text ? JSON.parse(text) : null; } catch (e) { data = { error: text }; }
  if (!res.ok) {
    const err = new Error((data && data.error) || `${method} ${path}: HTTP ${res.status}`);
    err.status = res.status;
    throw err;
  }
  return data;
}

function sessionPath(rest = '') { return `/api/sessions/${S.id}${rest}`; }

// One request of a kind in flight: a call meanwhile runs it once more when it ends (so the latest
// wins), and at most once every `ms`.
function single(f, ms = 0) {
  let busy = false, again = false, last = 0;
  const run = async () => {
    if (busy) { again = true; return; }
    busy = true;
    const wait = last + ms - Date.now();
    if (wait > 0) await sleep(wait);
    last = Date.now();
    try { await f(); } finally { busy = false; }
    if (again) { again = false; run(); }
  };
  return run;
}

async function act(path, body) {
  try {
    const state = await api('POST', sessionPath(path), body || {});
    if (state && state.id) showState(state);
    clearMessage();
    refreshTimeline();  // markers: a reset, new panels, steps taken
    return state;
  } catch (e) {
    if (e.status === 404) return expired();
    showMessage(e.message);
    if (S.state) showState(S.state);  // controls back to what the server has
    return null;
  }
}

function showMessage(text, info = false) {
  const m = $('message');
  m.textContent = text;
  m.classList.toggle('info', info);
  m.classList.remove('hidden');
}
function clearMessage() { $('message').classList.add('hidden'); }
function flash(text) {
  showMessage(text, true);
  clearTimeout(S.flashTimer);
  S.flashTimer = setTimeout(clearMessage, 2000);
}

function expired() {
  showMessage('This session has closed (idle too long, or the server restarted). Reload the page for a new one.');
  if (S.events) S.events.close();
  return null;
}

// ---- start ----

async function start() {
  let scenes, server;
  try {
    [scenes, S.methods, server] = await Promise.all([api('GET', '/api/scenes'), api('GET', '/api/methods'), api('GET', '/api/server')]);
  } catch (e) {
    showMessage(`The server does not answer: ${e.message}`);
    return;
  }
  for (const s of S.methods.settings) S.settingByKey[s.key] = s;
  fillSelect($('scene'), scenes.scenes.map((s) => [s.name, `${s.name} (${s.bodies} bodies)`]));
  fillSelect($('algo'), S.methods.algorithms.map((a) => [a.name, `${a.name}: ${a.title}`]));
  fillSelect($('colour'), S.methods.colours.map((c) => [c, c]));
  const presets = S.settingByKey.preset.choices;
  for (const p of presets) $('preset').add(new Option(p, p));
  buildControls();
  if (server.lab) {
    $('lab-link').classList.remove('hidden');
    api('GET', '/api/lab').then((lab) => { if (lab.files.length) $('lab-link').href = lab.files[0].url; });
  }
  if (!server.clips) for (const b of ['clip-last', 'clip-next']) $(b).disabled = true;

  // A recording when the address asks for one (?recording=NAME&time=T&body=B, or recordings=a,b side
  // by side; the atlas's "inspect" links add focus=k: the server opens panel k's first failure) or
  // the server was given one (--open); else a scene (#scene=...&methods=...).
  const query = new URLSearchParams(location.search);
  const params = new URLSearchParams(location.hash.slice(1));
  const listed = (v) => (v || '').split(',').filter(Boolean);
  let recording = null;
  if (query.get('recording')) recording = { recording: query.get('recording') };
  else if (listed(query.get('recordings')).length) recording = { recordings: listed(query.get('recordings')) };
  else if (server.open && server.open.length)
    recording = server.open.length === 1 ? { recording: server.open[0] } : { recordings: server.open };
  const focus = query.get('focus');
  if (recording && focus !== null && /^\d+$/.test(focus)) recording.focus = Number(focus);
  let state = null;
  if (recording) {
    try {
      state = await api('POST', '/api/sessions', recording);
    } catch (e) {
      showMessage(`${recording.recording || recording.recordings.join(', ')}: ${e.message}`);
    }
  }
  if (!state) {
    const wanted = params.get('scene');
    const scene = scenes.scenes.some((s) => s.name === wanted) ? wanted
      : scenes.scenes.some((s) => s.name === 'pyramid') ? 'pyramid' : scenes.scenes[0].name;
    const body = { scene, play: params.get('play') !== '0' };
    if (params.get('methods')) body.methods = params.get('methods');
    try {
      state = await api('POST', '/api/sessions', body);
    } catch (e) {
      showMessage(e.message);
      return;
    }
  }
  attach(state);
  bindControls();
  bindMouse();
  setInterval(() => { if (S.stats && S.stats.playing) refreshTimeline(); }, 1000);
  window.addEventListener('pagehide', () => navigator.sendBeacon(sessionPath('/close')));
  // A server that keeps recordings says which it was given (`open`); one without has no Recordings box.
  if ('open' in server) listRecordings();
  else $('recordings-box').classList.add('hidden');
  if (recording && state.timeline && state.timeline.recorded) {
    const time = Number(query.get('time'));
    if (query.get('time') !== null && Number.isFinite(time)) await act('/scrub', { time });
    else if (!query.has('time') && !('focus' in recording)) await act('/play', { speed: Number($('speed').value) });
    if (query.get('body')) await select({ body: query.get('body') });
  }
}

// The page shows session `state` from now on: its stream, events, timeline and selection.
function attach(state) {
  if (S.events) S.events.close();
  S.id = state.id;
  S.timeline = null;
  S.markers = [];
  S.shownStep = null;
  S.e0 = undefined;
  for (const p of Object.values(plots)) p.clear();
  showState(state);
  $('view').src = sessionPath('/stream.mjpeg');
  $('download-frame').href = sessionPath('/frame.png');
  openEvents();
  refreshTimeline();
  refreshInspect();
}

function fillSelect(sel, items) {
  sel.innerHTML = '';
  for (const [value, text] of items) sel.add(new Option(text, value));
}

// ---- solver controls, from the settings table ----

// Every setting the schema resolves, as /api/methods gives it: the main ones (control.main) first,
// the rest under "All settings"; the algorithm and the preset have controls of their own.
function buildControls() {
  const main = $('solver-controls'), more = $('more-controls');
  for (const s of S.methods.settings) {
    if (!s.resolved || s.key === 'algorithm') continue;
    const ui = { label: s.control.main ? s.control.label : s.key.replace(/_/g, ' '), ...(s.control.slider || {}) };
    (s.control.main ? main : more).appendChild(control(s, ui));
  }
}

function control(spec, ui) {
  const label = document.createElement('label');
  label.dataset.key = spec.key;
  label.title = `${spec.help} (${spec.expected})`;
  label.appendChild(document.createTextNode(ui.label));
  if (spec.kind === 'flag') {
    const box = document.createElement('input');
    box.type = 'checkbox';
    box.id = `set-${spec.key}`;
    box.addEventListener('change', () => changeSetting(spec.key, box.checked));
    label.appendChild(box);
    return label;
  }
  if (spec.kind === 'choice') {
    const sel = document.createElement('select');
    sel.id = `set-${spec.key}`;
    for (const c of spec.choices) sel.add(new Option(c, c));
    sel.addEventListener('change', () => changeSetting(spec.key, sel.value));
    label.appendChild(sel);
    return label;
  }
  // A number: a slider over the useful part of the range and a field for any value in it.
  const r = spec.range;
  const slider = document.createElement('input');
  slider.type = 'range';
  slider.min = ui.min !== undefined ? ui.min : r.min;
  slider.max = ui.max !== undefined ? ui.max : Math.min(r.max, r.min + 100);
  slider.step = ui.step || (spec.kind === 'integer' ? 1 : 'any');
  const field = document.createElement('input');
  field.type = 'number';
  field.id = `set-${spec.key}`;
  field.step = spec.kind === 'integer' ? 1 : 'any';
  const send = debounce((v) => changeSetting(spec.key, v), 200);
  slider.addEventListener('input', () => { field.value = slider.value; send(Number(slider.value)); });
  field.addEventListener('change', () => {
    const v = Number(field.value);
    if (field.value === '' || !Number.isFinite(v)) return showMessage(`${spec.key}: expected ${spec.expected}, got "${field.value}"`);
    slider.value = v;
    changeSetting(spec.key, v);
  });
  label.appendChild(slider);
  label.appendChild(field);
  return label;
}

function debounce(f, ms) {
  let t = null;
  return (...a) => { clearTimeout(t); t = setTimeout(() => f(...a), ms); };
}

function panelTarget() {
  const v = $('panel').value;
  return v === '' || v === 'all' ? {} : { panel: Number(v) };
}

function changeSetting(key, value) {
  return act('/settings', { ...panelTarget(), settings: { [key]: value } });
}

// What the server has, into the controls.
function showState(state) {
  S.state = state;
  const multi = state.panels.length > 1;
  $('panel-row').classList.toggle('hidden', !multi);
  const sel = $('panel'), keep = sel.value;
  const options = [['all', 'every panel']].concat(state.panels.map((p, i) => [String(i), `panel ${i + 1}: ${p.method}`]));
  if ([...sel.options].map((o) => o.value + o.text).join() !== options.map((o) => o.join('')).join()) {
    fillSelect(sel, options);
    if (options.some((o) => o[0] === keep)) sel.value = keep;
  }
  const p = state.panels[sel.value && sel.value !== 'all' ? Number(sel.value) : 0] || state.panels[0];
  const set = p.settings;
  // A recorded session is named after its recording, not a scene file: shown as such.
  if (![...$('scene').options].some((o) => o.value === state.scene)) {
    for (const o of [...$('scene').options]) if (o.dataset.recording) o.remove();
    const o = new Option(`recording: ${state.scene}`, state.scene);
    o.dataset.recording = '1';
    $('scene').add(o);
  }
  $('scene').value = state.scene;
  $('algo').value = set.algorithm;
  for (const label of document.querySelectorAll('#solver-controls label, #more-controls label')) {
    const key = label.dataset.key, v = set[key];
    const input = $(`set-${key}`);
    if (document.activeElement !== input) {
      if (input.type === 'checkbox') input.checked = !!v;
      else input.value = typeof v === 'number' ? +v.toPrecision(6) : v;
      const slider = label.querySelector('input[type=range]');
      if (slider && document.activeElement !== slider) slider.value = v;
    }
    // What the algorithm does not use is greyed (and refused by the server).
    const unused = !S.settingByKey[key].takes.includes(set.algorithm);
    label.classList.toggle('disabled', unused);
    label.querySelectorAll('input,select').forEach((i) => { i.disabled = unused; });
  }
  $('preset').disabled = !S.settingByKey.preset.takes.includes(set.algorithm);
  $('settings-line').textContent = state.panels.map((q) => q.line).join(' | ');
  showPlaying(state.playing, state.speed);
  // Camera and view.
  const cams = state.cameras.map((c) => [c, c]);
  if ([...$('camera-preset').options].map((o) => o.value).join() !== state.cameras.join()) fillSelect($('camera-preset'), cams);
  $('camera-preset').value = state.cameras.includes(state.camera.preset) ? state.camera.preset : '';
  const bodies = [['', '(none)']].concat(state.bodies.slice(0, 500).map((b) => [b, b]));
  if ($('follow').options.length !== bodies.length || $('follow').dataset.scene !== state.scene) {
    fillSelect($('follow'), bodies);
    $('follow').dataset.scene = state.scene;
  }
  $('follow').value = state.camera.follow;
  if (document.activeElement !== $('orbit')) $('orbit').value = state.camera.orbit;
  $('colour').value = state.view.colour;
  $('contacts').checked = state.view.contacts;
  $('joints').checked = state.view.joints;
  $('hud').checked = state.view.hud;
  $('forces').checked = !!state.view.forces;
  $('joint_errors').checked = !!state.view.joint_errors;
  showClips(state.clips);
  if (state.timeline) showTimeline(state.timeline);
  if ('selected' in state && (state.selected || null) !== S.selected) {
    S.selected = state.selected || null;
    refreshInspect();
  }
}

function showPlaying(playing, speed) {
  $('play').classList.toggle('on', playing && speed > 0);
  $('reverse').classList.toggle('on', playing && speed < 0);
  $('pause').classList.toggle('on', !playing);
}

// ---- buttons and fields ----

function bindControls() {
  $('play').onclick = () => act('/play', { speed: Number($('speed').value) });
  $('reverse').onclick = () => act('/play', { speed: -Number($('speed').value) });
  $('pause').onclick = () => act('/pause');
  $('step').onclick = () => act('/step', { count: 1 });
  $('step-back').onclick = () => act('/step', { count: -1 });
  $('live').onclick = () => act('/scrub', { live: true });
  $('reset').onclick = () => act('/reset');
  // A new speed keeps the direction played.
  $('speed').onchange = () => act('/play', { speed: (S.stats && S.stats.speed < 0 ? -1 : 1) * Number($('speed').value) });
  $('seek').onchange = () => act('/seek', { time: Number($('seek').value) });
  $('scene').onchange = () => act('/scene', { scene: $('scene').value });
  $('algo').onchange = () => changeSetting('algorithm', $('algo').value);
  $('panel').onchange = () => showState(S.state);
  $('preset').onchange = () => { if ($('preset').value) changeSetting('preset', $('preset').value); };
  $('compare-apply').onclick = () => act('/panels', { methods: $('compare-input').value });
  $('compare-single').onclick = () => {
    const p = S.state.panels[0];
    act('/panels', { methods: p.method === 'scene' ? p.settings.algorithm : p.method });
  };
  for (const a of document.querySelectorAll('.examples a'))
    a.onclick = (e) => {
      e.preventDefault();
      $('compare-input').value = a.dataset.methods;
      act('/panels', { methods: a.dataset.methods });
    };
  $('camera-preset').onchange = () => act('/camera', { preset: $('camera-preset').value });
  $('follow').onchange = () => act('/camera', { follow: $('follow').value });
  $('orbit').onchange = () => act('/camera', { orbit: Number($('orbit').value) });
  $('colour').onchange = () => act('/view', { colour: $('colour').value });
  for (const k of ['contacts', 'joints', 'forces', 'joint_errors', 'hud']) $(k).onchange = () => act('/view', { [k]: $(k).checked });
  bindTimeline();
  $('inspect-clear').onclick = () => select({ body: null });
  $('worst').onclick = () => jumpToWorst($('worst-kind').value);
  $('rec-file').onchange = () => uploadRecording($('rec-file').files[0]);
  $('rec-refresh').onclick = () => listRecordings();
  $('rec-open').onclick = () => {
    const names = [...document.querySelectorAll('#recordings input:checked')].map((b) => b.value);
    if (!names.length) return flash('tick one or more recordings first');
    openRecording(names.length === 1 ? { recording: names[0] } : { recordings: names });
  };
  $('push-speed').oninput = () => { $('push-speed-out').textContent = $('push-speed').value; };
  $('clip-last').onclick = () => makeClip('last');
  $('clip-next').onclick = () => makeClip('next');
  document.addEventListener('keydown', (e) => {
    if (e.target.tagName === 'INPUT' || e.target.tagName === 'SELECT') return;
    if (e.key === ' ') { e.preventDefault(); act(S.state.playing ? '/pause' : '/play'); }
    else if (e.key === 's' || e.key === 'ArrowRight') act('/step', { count: 1 });
    else if (e.key === 'ArrowLeft') act('/step', { count: -1 });
    else if (e.key === 'r') act('/reset');
  });
}

// ---- the view: orbit, pan, zoom, push ----

function bindMouse() {
  const img = $('view');
  let down = null;
  img.addEventListener('contextmenu', (e) => e.preventDefault());
  img.addEventListener('pointerdown', (e) => {
    img.setPointerCapture(e.pointerId);
    down = { x: e.clientX, y: e.clientY, lastX: e.clientX, lastY: e.clientY, moved: false,
             pan: e.shiftKey || e.button === 1 || e.button === 2 };
  });
  img.addEventListener('pointermove', (e) => {
    if (!down) return;
    const dx = e.clientX - down.lastX, dy = e.clientY - down.lastY;
    if (!down.moved && Math.hypot(e.clientX - down.x, e.clientY - down.y) < 4) return;
    down.moved = true;
    img.classList.add('dragging');
    down.lastX = e.clientX;
    down.lastY = e.clientY;
    // In the session's pixels (its size, whatever size the frames are drawn at).
    const scale = img.clientWidth ? ((S.state && S.state.width) || img.naturalWidth || img.clientWidth) / img.clientWidth : 1;
    if (down.pan || e.shiftKey) queueCamera({ pan: [dx * scale, dy * scale] });
    else queueCamera({ rotate: [-dx * 0.3, dy * 0.3] });
  });
  img.addEventListener('pointerup', (e) => {
    img.classList.remove('dragging');
    if (down && !down.moved && e.button === 0) {
      if (e.shiftKey) push(e);
      else select(framePixel(e));
    }
    down = null;
  });
  img.addEventListener('wheel', (e) => {
    e.preventDefault();
    queueCamera({ zoom: Math.exp(Math.max(-200, Math.min(200, e.deltaY)) * 0.0015) });
  }, { passive: false });
}

// Camera moves are summed while a request is out, so a fast drag sends a few, not hundreds.
function queueCamera(delta) {
  const q = S.cameraQueue || {};
  if (delta.rotate) q.rotate = [(q.rotate ? q.rotate[0] : 0) + delta.rotate[0], (q.rotate ? q.rotate[1] : 0) + delta.rotate[1]];
  if (delta.pan) q.pan = [(q.pan ? q.pan[0] : 0) + delta.pan[0], (q.pan ? q.pan[1] : 0) + delta.pan[1]];
  if (delta.zoom) q.zoom = (q.zoom || 1) * delta.zoom;
  S.cameraQueue = q;
  flushCamera();
}

async function flushCamera() {
  if (S.cameraBusy || !S.cameraQueue) return;
  const q = S.cameraQueue;
  S.cameraQueue = null;
  if (q.rotate) q.rotate = q.rotate.map((v) => Math.max(-360, Math.min(360, v)));
  if (q.zoom) q.zoom = Math.max(0.01, Math.min(100, q.zoom));
  S.cameraBusy = true;
  try {
    await api('POST', sessionPath('/camera'), q);
  } catch (e) {
    showMessage(e.message);
  }
  S.cameraBusy = false;
  flushCamera();
}

// The pixel under the pointer in the session's size, which the API's x and y are in (frames drawn
// smaller while the drawing cannot keep up are shown stretched to it).
function framePixel(e) {
  const img = $('view');
  const r = img.getBoundingClientRect();
  const w = (S.state && S.state.width) || img.naturalWidth, h = (S.state && S.state.height) || img.naturalHeight;
  const clamp = (v, n) => Math.max(0, Math.min(n - 1, v));
  return { x: clamp(((e.clientX - r.left) / r.width) * w, w), y: clamp(((e.clientY - r.top) / r.height) * h, h) };
}

async function push(e) {
  const { x, y } = framePixel(e);
  try {
    const hit = await api('POST', sessionPath('/push'), { x, y, speed: Number($('push-speed').value) });
    if (hit.hit) showMessage(`pushed ${hit.name}`, true);
    else showMessage('no body there', true);
    setTimeout(clearMessage, 1500);
  } catch (err) {
    showMessage(err.message);
  }
}

// ---- the timeline: the kept steps, scrubbed; markers above the slider ----

function bindTimeline() {
  const sl = $('scrub');
  sl.addEventListener('pointerdown', () => { S.scrubDragging = true; });
  const done = () => { S.scrubDragging = false; };
  sl.addEventListener('pointerup', done);
  sl.addEventListener('pointercancel', done);
  sl.addEventListener('change', done);
  sl.addEventListener('input', () => scrubTo({ time: Number(sl.value) }));
}

function scrubTo(body) {
  S.scrubWanted = body;
  sendScrub();
}

// While dragging, one scrub in flight; the position reached meanwhile goes next.
const sendScrub = single(async () => {
  const body = S.scrubWanted;
  if (!body) return;
  S.scrubWanted = null;
  try {
    showState(await api('POST', sessionPath('/scrub'), body));
  } catch (e) {
    if (e.status === 404) return expired();
    showMessage(e.message);
  }
  if (!S.scrubWanted) refreshTimeline();
});

// The span, the shown step and whether it is live, from the state or a stats event (same fields).
function showTimeline(t) {
  const old = S.timeline;
  S.timeline = { ...(old || {}), ...t };
  const tl = S.timeline;
  const sl = $('scrub');
  sl.min = tl.first;
  sl.max = tl.last;
  if (!S.scrubDragging && !S.scrubWanted) sl.value = tl.shown;
  $('shown-time').textContent = `t = ${tl.shown.toFixed(3)} s`;
  $('shown-time').dataset.time = tl.shown;
  $('shown-step').textContent = `step ${tl.shown_step}`;
  $('shown-step').dataset.step = tl.shown_step;
  const badge = $('shown-badge');
  badge.textContent = tl.recorded ? (tl.live ? 'recording: its end' : 'recording') : tl.live ? 'live' : 'the past';
  badge.className = tl.live && !tl.recorded ? 'badge ok' : 'badge past';
  $('kept-span').textContent = `kept ${tl.first.toFixed(2)}-${tl.last.toFixed(2)} s`;
  if (!old || old.first !== tl.first || old.last !== tl.last) layoutMarkers();
  placeCursor();
  if (tl.shown_step !== S.shownStep) {
    S.shownStep = tl.shown_step;
    refreshInspect();
  }
}

const refreshTimeline = single(async () => {
  if (!S.id) return;
  let t;
  try {
    t = await api('GET', sessionPath('/timeline'));
  } catch (e) {
    return;  // the next call says it (an expired session shows on the next action)
  }
  S.markers = t.markers || [];
  const { markers, ...span } = t;
  showTimeline(span);
  layoutMarkers();
}, 250);

const MARKER_ROW = 10;  // [px] a strip per panel

function xOf(time) {
  const tl = S.timeline, span = tl.last - tl.first;
  return span > 0 ? (100 * (time - tl.first)) / span : 0;
}

function panelName(i) {
  const p = S.state && S.state.panels[i];
  return !p ? `panel ${i + 1}` : S.state.panels.length > 1 ? `panel ${i + 1} (${p.method})` : p.method;
}

function layoutMarkers() {
  const box = $('markers'), tl = S.timeline;
  const rows = Math.max(1, S.state ? S.state.panels.length : 1);
  box.style.height = `${rows * MARKER_ROW + 2}px`;
  box.innerHTML = '';
  if (!tl) return;
  for (const m of S.markers) {
    if (m.time < tl.first || m.time > tl.last) continue;  // no longer kept
    const d = document.createElement('div');
    d.className = `marker k-${m.kind}`;
    d.style.left = `${xOf(m.time)}%`;
    d.style.top = `${1 + m.panel * MARKER_ROW}px`;
    d.style.height = `${MARKER_ROW - 2}px`;
    d.title = `${panelName(m.panel)}, t = ${m.time.toFixed(3)} s (step ${m.step}): ${m.text}`;
    Object.assign(d.dataset, { kind: m.kind, panel: m.panel, step: m.step, time: m.time });
    if (m.body) d.dataset.body = m.body;
    d.onclick = () => jumpToMarker(m);
    box.appendChild(d);
  }
  const c = document.createElement('div');
  c.className = 'cursor';
  c.id = 'markers-cursor';
  box.appendChild(c);
  placeCursor();
}

function placeCursor() {
  const c = $('markers-cursor');
  if (c && S.timeline) c.style.left = `${xOf(S.timeline.shown)}%`;
}

async function jumpToMarker(m) {
  await act('/scrub', { time: m.time });
  if (m.body) await select({ body: m.body });
  flash(`${panelName(m.panel)}: ${m.text}`);
}

async function jumpToWorst(kind) {
  try {
    const r = await api('POST', sessionPath('/worst'), { kind });
    showInspect(r.inspect);
    showState(await api('GET', sessionPath()));
    refreshTimeline();
    flash(r.marker.text || `worst ${kind} at t = ${r.marker.time} s`);
  } catch (e) {
    if (e.status === 404) return expired();
    showMessage(e.message);
  }
}

// ---- the inspector: the selected body at the shown step, per panel ----

// body: {x, y} (a pixel of the frame), {body: name} or {body: null}.
async function select(body) {
  try {
    const j = await api('POST', sessionPath('/select'), body);
    showInspect(j);
    if (!j.body && 'x' in body) flash('no body there');
  } catch (e) {
    if (e.status === 404) return expired();
    showMessage(e.message);
  }
}

// Asked when the shown step or the selection changes; one request in flight, 5 a second at most.
const refreshInspect = single(async () => {
  if (!S.id) return;
  if (!S.selected) return showInspect({ body: null, panels: [] });
  try {
    showInspect(await api('GET', sessionPath('/inspect')));
  } catch (e) {
    if (e.status === 404) expired();
  }
}, 200);

// Enough digits to tell steps apart, without float noise: 6 significant.
function fmt6(v) {
  if (v === null || v === undefined) return '-';
  if (Array.isArray(v)) return v.map(fmt6).join(', ');
  if (typeof v === 'number') return Number.isFinite(v) ? String(Number(v.toPrecision(6))) : String(v);
  if (typeof v === 'object') return shapeText(v);
  return String(v);
}

// {"kind": "box", "half_extents": [...]} -> "box, half extents 0.5, 0.5, 0.5"
function shapeText(shape) {
  if (!shape || typeof shape !== 'object') return fmt6(shape);
  const head = shape.kind || shape.type || '';
  const rest = Object.entries(shape).filter(([k]) => k !== 'kind' && k !== 'type')
    .map(([k, v]) => `${k.replace(/_/g, ' ')} ${fmt6(v)}`);
  return [head, ...rest].filter(Boolean).join(', ');
}

const INSPECT_ROWS = [
  ['name', 'body'], ['shape', 'shape'], ['mass', 'mass [kg]'], ['inertia', 'inertia [kg m\u00b2]'],
  ['position', 'position [m]'], ['orientation', 'orientation (w, x, y, z)'], ['velocity', 'velocity [m/s]'],
  ['angular_velocity', 'angular velocity [rad/s]'], ['kinetic', 'kinetic energy [J]'],
];
const CONTACT_COLUMNS = [
  ['other', 'other'], ['point', 'point [m]'], ['normal', 'normal'], ['depth', 'depth [m]'],
  ['normal_impulse', '\u03bbn [N s]'], ['friction', 'friction [N s]'], ['twist', 'twist [N m s]'],
];
const JOINT_COLUMNS = [
  ['name', 'joint'], ['kind', 'kind'], ['other', 'other'], ['error', 'error [m]'],
  ['linear_impulse', 'linear impulse [N s]'], ['angular_impulse', 'angular impulse [N m s]'],
];
const MAX_ROWS = 40;  // contacts or joints listed per panel

function showInspect(j) {
  S.inspect = j;
  S.selected = j.body || null;
  $('inspect-body').textContent = j.body || '(none)';
  const box = $('inspect-panels');
  if (!j.body) {
    box.innerHTML = '<p class="line">Click a body in the stream to inspect it (shift-click pushes it).</p>';
    return;
  }
  const cell = (tag, field, v) => `<${tag} data-field="${field}">${escapeHtml(fmt6(v))}</${tag}>`;
  const list = (caption, attr, rows, columns) => {
    if (!rows || !rows.length) return `<p class="line" data-${attr}s="0">no ${caption}</p>`;
    const head = `<tr>${columns.map(([, label]) => `<th>${label}</th>`).join('')}</tr>`;
    const body = rows.slice(0, MAX_ROWS).map((r, k) =>
      `<tr data-${attr}="${k}">${columns.map(([key]) => cell('td', key, r[key])).join('')}</tr>`).join('');
    const more = rows.length > MAX_ROWS ? `<tr><td colspan="${columns.length}">and ${rows.length - MAX_ROWS} more</td></tr>` : '';
    const counted = `${rows.length} ${rows.length === 1 ? caption.slice(0, -1) : caption}`;
    return `<table class="list" data-${attr}s="${rows.length}"><caption>${counted}</caption>${head}${body}${more}</table>`;
  };
  box.innerHTML = j.panels.map((p) => `
    <div class="inspect-card" data-panel="${p.panel}">
      <h4>${escapeHtml(inspectTitle(p))} &middot;
        t = <span data-field="time">${fmt6(p.time)}</span> s &middot; step <span data-field="step">${p.step}</span></h4>
      <table class="kv">${INSPECT_ROWS.map(([key, label]) => `<tr><th>${label}</th>${cell('td', key, p[key])}</tr>`).join('')}</table>
      ${list('contacts', 'contact', p.contacts, CONTACT_COLUMNS)}
      ${list('joints', 'joint', p.joints, JOINT_COLUMNS)}
    </div>`).join('');
}

function inspectTitle(p) {
  const method = !p.method || p.method === 'scene' ? "the scene's settings" : p.method;
  return S.state && S.state.panels.length > 1 ? `panel ${p.panel + 1}: ${method}` : method;
}

// ---- recordings: the server's, or a .rec uploaded ----

async function listRecordings() {
  let r;
  try {
    r = await api('GET', '/api/recordings');
  } catch (e) {
    $('recordings').innerHTML = `<p class="line">${escapeHtml(e.message)}</p>`;
    return;
  }
  const box = $('recordings');
  box.innerHTML = '';
  if (!r.recordings.length) box.innerHTML = '<p class="line">none yet: open a .rec file</p>';
  for (const rec of r.recordings) {
    const label = document.createElement('label');
    const tick = document.createElement('input');
    tick.type = 'checkbox';
    tick.value = rec.name;
    const a = document.createElement('a');
    a.href = `?recording=${encodeURIComponent(rec.name)}`;
    a.textContent = rec.name;
    a.title = 'Open this recording';
    a.onclick = (e) => { e.preventDefault(); openRecording({ recording: rec.name }); };
    const info = document.createElement('span');
    info.className = 'info';
    const facts = [];
    if (rec.scene) facts.push(rec.scene);
    if (rec.panels) facts.push(`${rec.panels} panel${rec.panels === 1 ? '' : 's'}`);
    if (rec.frames) facts.push(`${rec.frames} frames`);
    if (rec.seconds) facts.push(`${fmt6(+rec.seconds.toFixed(2))} s`);
    if (rec.bytes !== undefined) facts.push(`${(rec.bytes / 1e6).toFixed(2)} MB`);
    info.textContent = facts.join(', ');
    label.append(tick, a, info);
    box.appendChild(label);
  }
}

async function uploadRecording(file) {
  if (!file) return;
  showMessage(`uploading ${file.name} (${(file.size / 1e6).toFixed(1)} MB)...`, true);
  try {
    const r = await api('POST', `/api/recordings?name=${encodeURIComponent(file.name)}`, file);
    $('rec-file').value = '';
    await openRecording({ recording: r.name });
    listRecordings();
  } catch (e) {
    showMessage(`${file.name}: ${e.message}`);
  }
}

// A session on the recording(s) instead of this one; the address says which, for a reload.
async function openRecording(body) {
  const old = S.id;
  let state;
  try {
    state = await api('POST', '/api/sessions', body);
  } catch (e) {
    if (e.status !== 503 || !old) return showMessage(e.message);
    // At the server's cap: this tab's session makes room.
    await api('DELETE', `/api/sessions/${old}`).catch(() => {});
    try { state = await api('POST', '/api/sessions', body); } catch (e2) { return showMessage(e2.message); }
  }
  attach(state);
  // The old session goes once the new stream shows a frame: the browser holds the old stream until
  // then, and closing it sooner would cut it short (an error in the console).
  if (old && old !== state.id) {
    let closed = false;
    const close = () => {
      if (closed) return;
      closed = true;
      api('DELETE', `/api/sessions/${old}`).catch(() => {});
    };
    $('view').addEventListener('load', close, { once: true });
    setTimeout(close, 3000);
  }
  const q = body.recording ? `recording=${encodeURIComponent(body.recording)}` : `recordings=${body.recordings.map(encodeURIComponent).join(',')}`;
  history.replaceState(null, '', `?${q}`);
  clearMessage();
  act('/play', { speed: Number($('speed').value) });
}

// ---- clips ----

async function makeClip(mode) {
  try {
    const clip = await api('POST', sessionPath('/clips'), { mode, seconds: 5 });
    showMessage(mode === 'last' ? 'encoding the last 5 s...' : 'recording the next 5 s...', true);
    pollClip(clip.id);
  } catch (e) {
    showMessage(e.message);
  }
}

async function pollClip(id) {
  for (;;) {
    await new Promise((r) => setTimeout(r, 500));
    let c;
    try { c = await api('GET', sessionPath(`/clips/${id}`)); } catch (e) { return showMessage(e.message); }
    if (c.state === 'done') {
      clearMessage();
      const s = await api('GET', sessionPath());
      showClips(s.clips);
      return;
    }
    if (c.state === 'failed') return showMessage(`clip ${id} failed: ${c.error}`);
  }
}

function showClips(clips) {
  const box = $('clips');
  box.innerHTML = '';
  for (const c of clips.filter((c) => c.state === 'done')) {
    const a = document.createElement('a');
    a.href = c.url;
    a.download = '';
    a.textContent = `clip ${c.id} (${c.seconds} s, ${(c.bytes / 1e6).toFixed(1)} MB)`;
    box.appendChild(a);
  }
}

// ---- stats ----

const plots = {};

function openEvents() {
  if (!plots.cost) {
    plots.cost = new Plot($('plot-cost'), $('cost-legend'), { stacked: true });
    plots.error = new Plot($('plot-error'), $('error-legend'));
    plots.energy = new Plot($('plot-energy'), $('energy-legend'));
  }
  S.events = new EventSource(sessionPath('/events'));
  S.events.addEventListener('stats', (e) => showStats(JSON.parse(e.data)));
  S.events.onerror = () => {
    api('GET', sessionPath()).catch((e) => { if (e.status === 404) expired(); });
  };
}

function showStats(st) {
  S.stats = st;
  const p0 = st.panels[0];
  $('time').textContent = `t = ${p0.time.toFixed(2)} s`;
  const rt = $('realtime');
  const diverged = st.panels.some((p) => p.diverged);
  // A status without a diverged panel is where playing stopped ("at the first kept step", "the end
  // of the recording") or a drawing problem: said in the badge, not as a divergence.
  if (diverged) {
    rt.className = 'badge bad';
    rt.textContent = 'paused: diverged';
    rt.title = st.status;
    if (st.status && !S.shownStatus) { showMessage(st.status); S.shownStatus = true; }
  } else if (st.status && !st.playing) {
    rt.className = /^cannot /.test(st.status) ? 'badge bad' : 'badge ok';
    rt.textContent = `paused: ${st.status}`;
    rt.title = st.status;
  } else if (st.seeking) {
    rt.className = 'badge slow';
    rt.textContent = 'seeking';
  } else if (st.playing && st.behind) {
    rt.className = 'badge slow';
    rt.textContent = `behind real time: ${st.achieved.toFixed(2)}\u00d7`;
    rt.title = 'the physics cannot keep up with the asked speed';
  } else {
    rt.className = 'badge ok';
    rt.textContent = st.playing ? `real time ${st.fps.toFixed(0)} fps` : 'paused';
    rt.title = '';
    if (st.size_note) {
      rt.className = 'badge slow';
      rt.textContent += `, drawn at ${st.frame_width}x${st.frame_height}`;
      rt.title = st.size_note;
    }
  }
  if (!diverged) S.shownStatus = false;
  if (S.state) {
    S.state.playing = st.playing;
    showPlaying(st.playing, st.speed);
  }
  if (st.shown !== undefined) showTimeline(st);
  for (const p of Object.values(plots)) p.setCursor(st.shown !== undefined ? st.shown : p0.time);
  // The plots are the run's history: they grow while the newest step is shown (a recording: while
  // it plays forward), not while scrubbing.
  if (st.live === false && !(st.recorded && st.playing && st.speed > 0)) return showStatsTable(st);
  // Plots: a lone panel shows its stages; a grid the total of each panel.
  const names = st.panels.map((p, i) => p.name || `panel ${i + 1}`);
  if (st.panels.length === 1) {
    plots.cost.setSeries(['s1 geometry', 's2 formulation', 's3 velocities', 's4 coordinates']);
    plots.cost.push(p0.time, [p0.s1_ms, p0.s2_ms, p0.s3_ms, p0.s4_ms]);
    plots.error.setSeries(['penetration', 'joint error']);
    plots.error.push(p0.time, [1e3 * p0.penetration, 1e3 * p0.joint_error]);
    plots.energy.setSeries(['kinetic', 'potential']);
    plots.energy.push(p0.time, [p0.kinetic, p0.potential - (S.e0 !== undefined && p0.time > 0 ? S.e0 : (S.e0 = p0.potential))]);
  } else {
    plots.cost.stacked = false;
    plots.cost.setSeries(names);
    plots.cost.push(p0.time, st.panels.map((p) => p.s1_ms + p.s2_ms + p.s3_ms + p.s4_ms));
    plots.error.setSeries(names);
    plots.error.push(p0.time, st.panels.map((p) => 1e3 * Math.max(p.penetration, p.joint_error)));
    plots.energy.setSeries(names);
    plots.energy.push(p0.time, st.panels.map((p) => p.kinetic));
  }
  if (st.panels.length === 1) plots.cost.stacked = true;
  if (p0.time === 0) S.e0 = undefined;
  showStatsTable(st);
}

function showStatsTable(st) {
  const names = st.panels.map((p, i) => p.name || `panel ${i + 1}`);
  const rows = [['', 'time [s]', 'step [ms]', 's1', 's2', 's3', 's4', 'contacts', 'penetration [mm]', 'joint error [mm]', 'kinetic [J]']];
  st.panels.forEach((p, i) => rows.push([
    names[i], p.time.toFixed(2), num(p.step_ms, 2), num(p.s1_ms, 2), num(p.s2_ms, 2), num(p.s3_ms, 2), num(p.s4_ms, 2),
    p.contacts, num(1e3 * p.penetration, 2), num(1e3 * p.joint_error, 2), num(p.kinetic, 2), p.diverged]));
  const html = rows.map((r, k) => `<tr>${r.slice(0, 11).map((c) => k === 0 ? `<th>${c}</th>` : `<td${r[11] ? ' class="bad"' : ''}>${escapeHtml(String(c))}</td>`).join('')}</tr>`).join('');
  $('stats').innerHTML = html +
    `<tr><td colspan="11">frame: physics ${num(st.physics_ms, 1)} ms, draw ${num(st.draw_ms, 1)} ms, JPEG ${num(st.encode_ms, 1)} ms (${(st.jpeg_bytes / 1024).toFixed(0)} KiB), ${num(st.fps, 1)} fps at ${st.frame_width}x${st.frame_height}${st.size_note ? ` (${escapeHtml(st.size_note)})` : ''}</td></tr>`;
}

function num(v, digits) { return v === null || v === undefined || !Number.isFinite(v) ? '-' : v.toFixed(digits); }
function escapeHtml(s) { return s.replace(/[&<>"]/g, (c) => ({ '&': '&amp;', '<': '&lt;', '>': '&gt;', '"': '&quot;' }[c])); }

start();
