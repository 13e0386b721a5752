// The page of `substep serve`: one session per tab, driven through the JSON API of
// docs/server.md; frames arrive as an MJPEG stream in the <img>, stats as server-sent events.
'use strict';

const $ = (id) => document.getElementById(id);
const S = {
  id: null, state: null, methods: null, settingByKey: {}, stats: null,
  events: null, cameraQueue: null, cameraBusy: false,
};

// ---- requests ----

async function api(method, path, body) {
  const init = { method, headers: {} };
  if (body !== undefined) {
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

async function act(path, body) {
  try {
    const state = await api('POST', sessionPath(path), body || {});
    if (state && state.id) showState(state);
    clearMessage();
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

  const params = new URLSearchParams(location.hash.slice(1));
  const wanted = params.get('scene');
  const scene = scenes.scenes.some((s) => s.name === wanted) ? wanted
    : scenes.scenes.some((s) => s.name === 'pyramid') ? 'pyramid' : scenes.scenes[0].name;
  const body = { scene, play: params.get('play') !== '0' };
  if (params.get('methods')) body.methods = params.get('methods');
  try {
    const state = await api('POST', '/api/sessions', body);
    S.id = state.id;
    showState(state);
  } catch (e) {
    showMessage(e.message);
    return;
  }
  $('view').src = sessionPath('/stream.mjpeg');
  $('download-frame').href = sessionPath('/frame.png');
  openEvents();
  bindControls();
  bindMouse();
  window.addEventListener('pagehide', () => navigator.sendBeacon(sessionPath('/close')));
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
  $('play').classList.toggle('on', state.playing);
  $('pause').classList.toggle('on', !state.playing);
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
  showClips(state.clips);
}

// ---- buttons and fields ----

function bindControls() {
  $('play').onclick = () => act('/play', { speed: Number($('speed').value) });
  $('pause').onclick = () => act('/pause');
  $('step').onclick = () => act('/step', { count: 1 });
  $('reset').onclick = () => act('/reset');
  $('speed').onchange = () => act('/play', { speed: Number($('speed').value) });
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
  for (const k of ['contacts', 'joints', 'hud']) $(k).onchange = () => act('/view', { [k]: $(k).checked });
  $('push-speed').oninput = () => { $('push-speed-out').textContent = $('push-speed').value; };
  $('clip-last').onclick = () => makeClip('last');
  $('clip-next').onclick = () => makeClip('next');
  document.addEventListener('keydown', (e) => {
    if (e.target.tagName === 'INPUT' || e.target.tagName === 'SELECT') return;
    if (e.key === ' ') { e.preventDefault(); act(S.state.playing ? '/pause' : '/play'); }
    else if (e.key === 's') act('/step', { count: 1 });
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
    const scale = img.naturalWidth ? img.naturalWidth / img.clientWidth : 1;
    if (down.pan || e.shiftKey) queueCamera({ pan: [dx * scale, dy * scale] });
    else queueCamera({ rotate: [-dx * 0.3, dy * 0.3] });
  });
  img.addEventListener('pointerup', (e) => {
    img.classList.remove('dragging');
    if (down && !down.moved && e.button === 0) push(e);
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

async function push(e) {
  const img = $('view');
  const r = img.getBoundingClientRect();
  const x = ((e.clientX - r.left) / r.width) * img.naturalWidth, y = ((e.clientY - r.top) / r.height) * img.naturalHeight;
  try {
    const hit = await api('POST', sessionPath('/push'), { x, y, speed: Number($('push-speed').value) });
    if (hit.hit) showMessage(`pushed ${hit.name}`, true);
    else showMessage('no body there', true);
    setTimeout(clearMessage, 1500);
  } catch (err) {
    showMessage(err.message);
  }
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
  plots.cost = new Plot($('plot-cost'), $('cost-legend'), { stacked: true });
  plots.error = new Plot($('plot-error'), $('error-legend'));
  plots.energy = new Plot($('plot-energy'), $('energy-legend'));
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
  if (diverged || st.status) {
    rt.className = 'badge bad';
    rt.textContent = 'paused: diverged';
    rt.title = st.status;
    if (st.status && !S.shownStatus) { showMessage(st.status); S.shownStatus = true; }
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
  }
  if (!diverged) S.shownStatus = false;
  if (S.state && st.playing !== S.state.playing) {
    S.state.playing = st.playing;
    $('play').classList.toggle('on', st.playing);
    $('pause').classList.toggle('on', !st.playing);
  }
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
  const rows = [['', 'time [s]', 'step [ms]', 's1', 's2', 's3', 's4', 'contacts', 'penetration [mm]', 'joint error [mm]', 'kinetic [J]']];
  st.panels.forEach((p, i) => rows.push([
    names[i], p.time.toFixed(2), num(p.step_ms, 2), num(p.s1_ms, 2), num(p.s2_ms, 2), num(p.s3_ms, 2), num(p.s4_ms, 2),
    p.contacts, num(1e3 * p.penetration, 2), num(1e3 * p.joint_error, 2), num(p.kinetic, 2), p.diverged]));
  const html = rows.map((r, k) => `<tr>${r.slice(0, 11).map((c) => k === 0 ? `<th>${c}</th>` : `<td${r[11] ? ' class="bad"' : ''}>${escapeHtml(String(c))}</td>`).join('')}</tr>`).join('');
  $('stats').innerHTML = html +
    `<tr><td colspan="11">frame: physics ${num(st.physics_ms, 1)} ms, draw ${num(st.draw_ms, 1)} ms, JPEG ${num(st.encode_ms, 1)} ms (${(st.jpeg_bytes / 1024).toFixed(0)} KiB), ${num(st.fps, 1)} fps</td></tr>`;
}

function num(v, digits) { return v === null || v === undefined || !Number.isFinite(v) ? '-' : v.toFixed(digits); }
function escapeHtml(s) { return s.replace(/[&<>"]/g, (c) => ({ '&': '&amp;', '<': '&lt;', '>': '&gt;', '"': '&quot;' }[c])); }

start();
