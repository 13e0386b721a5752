// The browser test of `substep serve` (CTest `browser_page`): Debian's chromium, headless, driven by
// playwright-core from npm (installed by scripts/test into the build folder; no browser download).
// It does what a user does: opens the page, starts a scene, watches the stream change and the
// stats arrive, switches the method, pushes a body (shift-click) and sees it move, opens the
// side-by-side view, downloads a PNG, and saves a screenshot; then the timeline: plays the ragdoll,
// scrubs back by dragging the slider (the frame changes, the time shown is the API's), steps back,
// selects a body by clicking it (the inspector's numbers are GET inspect's, and follow the shown
// step), jumps to the worst penetration, clicks a marker, turns on force arrows (the frame's pixels
// change) and saves browser_timeline.png; then a recording made by `substep run --record`,
// uploaded through the page's file input, opened by links (?recording=&time=&body=, the atlas's
// ?recordings=&focus=) and by a second server's --open.
//
//   node browser_test.mjs --substep build/app/substep --out build/browser [--chromium /usr/bin/chromium]
//       [--scenes assets/scenes]
import { spawn, spawnSync } from 'node:child_process';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';

const args = Object.fromEntries(process.argv.slice(2).reduce((acc, a, i, all) => {
  if (a.startsWith('--')) acc.push([a.slice(2), all[i + 1]]);
  return acc;
}, []));
const substep = args.substep;
const out = args.out || '.';
const executablePath = args.chromium || '/usr/bin/chromium';
const scenes = args.scenes || (substep ? path.resolve(path.dirname(substep), '../../assets/scenes') : '');
if (!substep || !fs.existsSync(substep)) fail(`--substep: expected the built substep binary, got ${substep}`);
if (!fs.existsSync(executablePath)) fail(`${executablePath}: no chromium (Debian: apt-get install chromium; scripts/test installs it)`);
fs.mkdirSync(out, { recursive: true });
let chromium;
try {
  ({ chromium } = await import('playwright-core'));
} catch (e) {
  fail(`playwright-core is not installed next to this script (scripts/test runs npm ci in ${path.dirname(process.argv[1])}): ${e.message}`);
}

function fail(message) {
  console.error(`browser test: FAILED: ${message}`);
  process.exitCode = 1;
  throw new Error(message);
}
function check(ok, message) {
  if (!ok) fail(message);
  console.log(`  ok: ${message}`);
}
const sleep = (ms) => new Promise((r) => setTimeout(r, ms));
async function until(what, f, seconds = 20) {
  const end = Date.now() + seconds * 1000;
  let last;
  while (Date.now() < end) {
    last = await f();
    if (last) return last;
    await sleep(100);
  }
  fail(`timed out after ${seconds} s waiting for ${what}`);
}

// The server, on a free port of loopback.
const server = spawn(substep, ['serve', '--port', '0', '--size', '640x360', '--fps', '20'], { stdio: ['ignore', 'pipe', 'pipe'] });
let serverOut = '';
server.stdout.on('data', (d) => { serverOut += d; });
server.stderr.on('data', (d) => { serverOut += d; });
const exited = new Promise((r) => server.on('exit', (code, signal) => r({ code, signal })));
let context;
const userDataDir = fs.mkdtempSync(path.join(os.tmpdir(), 'substep-chromium-'));

try {
  const port = await until('the server to print its address', () => {
    const m = serverOut.match(/http:\/\/127\.0\.0\.1:(\d+)\//);
    return m && Number(m[1]);
  });
  const base = `http://127.0.0.1:${port}`;
  console.log(`server at ${base}`);

  context = await chromium.launchPersistentContext(userDataDir, {
    executablePath,
    headless: true,
    acceptDownloads: true,
    viewport: { width: 1400, height: 1050 },
    args: ['--headless', '--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run', '--disable-background-networking',
           '--disable-component-update', '--disable-sync', '--disable-dev-shm-usage'],
  });
  const page = context.pages()[0] || await context.newPage();
  const errors = [];
  page.on('pageerror', (e) => errors.push(String(e)));
  page.on('console', (m) => { if (m.type() === 'error' && !/favicon/.test(m.text())) errors.push(`${m.text()} (${m.location().url} on ${page.url()})`); });

  // What the <img> shows now: a checksum of a region of the streamed frame, drawn into a canvas.
  const frameSum = (region) => page.evaluate((r) => {
    const img = document.getElementById('view');
    if (!img.naturalWidth) return null;
    const c = document.createElement('canvas');
    c.width = img.naturalWidth;
    c.height = img.naturalHeight;
    const g = c.getContext('2d');
    g.drawImage(img, 0, 0);
    const [x, y, w, h] = r ? [r[0] * c.width, r[1] * c.height, r[2] * c.width, r[3] * c.height] : [0, 0, c.width, c.height];
    const d = g.getImageData(Math.round(x), Math.round(y), Math.round(w), Math.round(h)).data;
    let s = 0;
    for (let i = 0; i < d.length; i += 4) s = (s * 31 + d[i] + 3 * d[i + 1] + 7 * d[i + 2]) % 1000000007;
    return s;
  }, region || null);
  const sessionId = () => page.evaluate(() => S.id);
  const api = async (p) => (await fetch(`${base}/api/sessions/${await sessionId()}${p}`)).json();

  console.log('load the page');
  await page.goto(`${base}/`);
  await until('the first frame in the stream', async () => (await frameSum()) !== null);
  check(await page.title() === 'substep', 'the page loads with its title');

  console.log('start a scene');
  await page.selectOption('#scene', 'stack');
  await until('the stack scene', async () => (await api('')).scene === 'stack');
  await page.click('#reset');
  await page.click('#play');
  await until('playing', async () => (await api('')).playing);
  const a = await frameSum();
  await sleep(1500);
  const b = await until('a changed frame', async () => { const s = await frameSum(); return s !== a && s; });
  check(a !== b, 'the streamed image changes while it plays');
  const t = await until('stats with t > 0.5 s', async () => {
    const text = await page.textContent('#time');
    const v = Number(text.replace(/[^0-9.]/g, ''));
    return v > 0.5 && v;
  });
  check(t > 0.5, `stats arrive (the page shows t = ${t} s)`);
  const rows = await page.$$eval('#stats tr', (r) => r.length);
  check(rows >= 2, 'the stats table has a row for the panel');

  console.log('switch the method');
  await page.selectOption('#algo', 'a5');
  await until('a5 in the settings line', async () => (await page.textContent('#settings-line')).startsWith('a5'));
  check((await api('')).panels[0].settings.algorithm === 'a5', 'the server runs a5');
  await page.fill('#set-substeps', '8');
  await page.press('#set-substeps', 'Enter');
  await until('n = 8', async () => (await api('')).panels[0].settings.substeps === 8);
  check(true, 'n changed to 8 from its field');

  console.log('push a body');
  await page.selectOption('#scene', 'box_on_ground');
  await until('the box scene', async () => (await api('')).scene === 'box_on_ground');
  await page.click('#pause');
  await page.click('#reset');
  await until('paused at t = 0', async () => { const s = await api(''); return !s.playing && s.time === 0; });
  await sleep(500);
  const centre = [0.3, 0.3, 0.4, 0.4];
  const before = await frameSum(centre);
  // Hard enough that the box slides for most of a second before friction stops it.
  await page.$eval('#push-speed', (r) => { r.value = '10'; r.dispatchEvent(new Event('input')); });
  const box = await page.$('#view');
  const bb = await box.boundingBox();
  await page.click('#view', { modifiers: ['Shift'], position: { x: bb.width / 2, y: bb.height / 2 } });
  await until('"pushed box"', async () => /pushed box/.test(await page.textContent('#message')));
  check(true, 'a shift-click on the box pushes it');
  await page.click('#play');
  // Friction stops the box within a second: watch the picture and the energy together.
  let maxKinetic = 0, moved = false;
  await until('the box to move', async () => {
    const st = await api('/stats');
    maxKinetic = Math.max(maxKinetic, st.panels[0].kinetic);
    moved = moved || (await frameSum(centre)) !== before;
    return moved && maxKinetic > 0.5;
  });
  check(moved, 'the box moves in the stream');
  check(maxKinetic > 0.5, `the pushed box moves (kinetic energy up to ${maxKinetic.toFixed(2)} J)`);

  console.log('side by side');
  await page.selectOption('#scene', 'pyramid');
  await until('the pyramid', async () => (await api('')).scene === 'pyramid');
  await page.fill('#compare-input', 'a2:m=4,a5:n=4');
  await page.click('#compare-apply');
  await until('two panels', async () => (await api('')).panels.length === 2);
  await until('the panel selector', async () => page.isVisible('#panel-row'));
  await until('two panel rows in the stats', async () => (await page.$$eval('#stats tr', (r) => r.length)) >= 4);
  check(true, 'the side-by-side view shows two panels');
  await page.click('#play');
  await sleep(2000);

  console.log('download a frame');
  const [download] = await Promise.all([page.waitForEvent('download'), page.click('#download-frame')]);
  const png = path.join(out, 'downloaded_frame.png');
  await download.saveAs(png);
  const bytes = fs.readFileSync(png);
  check(bytes.subarray(1, 4).toString() === 'PNG', `the downloaded frame is a PNG (${bytes.length} bytes)`);
  check(bytes.readUInt32BE(16) === 640 && bytes.readUInt32BE(20) === 360, 'of the session size, 640x360');

  const shot = path.join(out, 'screenshot.png');
  await page.screenshot({ path: shot, fullPage: true });
  check(fs.statSync(shot).size > 10000, `screenshot saved: ${shot}`);
  // ---- the timeline, the inspector, forces ----
  const post = async (p, body) => (await fetch(`${base}/api/sessions/${await sessionId()}${p}`, {
    method: 'POST', headers: { 'Content-Type': 'application/json' }, body: JSON.stringify(body || {}),
  })).json();

  console.log('timeline: play the ragdoll, pause, scrub back');
  await page.click('#compare-single');
  await until('one panel', async () => (await api('')).panels.length === 1);
  await page.selectOption('#scene', 'ragdoll');
  await until('the ragdoll', async () => (await api('')).scene === 'ragdoll');
  await page.click('#pause');
  await page.click('#reset');
  await until('paused at t = 0', async () => { const s = await api(''); return !s.playing && s.time === 0; });
  await page.click('#play');
  await until('3 s of kept steps', async () => (await api('')).timeline.last >= 3, 90);
  await page.click('#pause');
  await until('paused', async () => !(await api('')).playing);
  const tl0 = await api('/timeline');
  check(tl0.live && tl0.shown === tl0.last && tl0.first === 0 && tl0.last >= 3,
    `the timeline keeps ${tl0.first}-${tl0.last} s and shows the newest (live)`);
  const kept = (tl) => tl.markers.filter((m) => m.time >= tl.first && m.time <= tl.last);
  check(kept(tl0).length > 0, `the timeline has markers (${kept(tl0).map((m) => m.kind).join(', ')})`);
  await until('the markers on the strip', async () => (await page.$$('#markers .marker')).length === kept(tl0).length);
  check(true, `the page draws the ${kept(tl0).length} markers`);
  await sleep(800);  // the paused frame reaches the <img>
  const liveFrame = await frameSum();

  // Drag the slider's thumb from the right end to a third of the way.
  const sb = await (await page.$('#scrub')).boundingBox();
  const yMid = sb.y + sb.height / 2;
  await page.mouse.move(sb.x + sb.width - 6, yMid);
  await page.mouse.down();
  for (let k = 1; k <= 12; ++k) {
    await page.mouse.move(sb.x + sb.width - 6 - (k * (sb.width * 0.65)) / 12, yMid);
    await sleep(40);
  }
  await page.mouse.up();
  const back = await until('the page to show the step the API shows, in the past', async () => {
    const tl = (await api('')).timeline;
    const text = await page.textContent('#shown-time');
    const step = Number(await page.getAttribute('#shown-step', 'data-step'));
    return !tl.live && tl.shown < tl0.last - 1 && text === `t = ${tl.shown.toFixed(3)} s` && step === tl.shown_step && tl;
  });
  check(true, `dragging the slider scrubs back to t = ${back.shown} s (step ${back.shown_step}), the time shown is the API's`);
  check(Math.abs(Number(await page.inputValue('#scrub')) - back.shown) < 0.05, 'the slider sits at the shown time');
  await until('the frame of the past step', async () => (await frameSum()) !== liveFrame);
  check(true, 'the frame changes to the past step');
  await page.click('#step-back');
  await until('one kept step back', async () => (await api('')).timeline.shown_step === back.shown_step - 1);
  check(true, 'the step-back button goes one kept step back');
  await page.click('#reverse');
  await until('playing backwards', async () => { const s = await api(''); return s.playing && s.timeline.shown < back.shown - 0.2; });
  await page.click('#pause');
  const here = await until('paused in the past', async () => { const s = await api(''); return !s.playing && s.timeline; });
  check(here.shown < back.shown - 0.2 && here.shown > 0, `"back" plays backwards through the kept steps (to t = ${here.shown.toFixed(3)} s)`);

  console.log('inspector: click a body');
  const num6 = (v) => Number(v.toPrecision(6));
  const sameNumbers = (text, value) => {
    const want = [value].flat(Infinity).map(num6);
    const got = String(text).split(',').map((x) => Number(x.trim()));
    return got.length === want.length && got.every((g, i) => g === want[i]);
  };
  const readInspector = () => page.evaluate(() => {
    const fields = (root) => Object.fromEntries([...root.querySelectorAll('[data-field]')].map((e) => [e.dataset.field, e.textContent]));
    return [...document.querySelectorAll('.inspect-card')].map((c) => ({
      panel: Number(c.dataset.panel),
      fields: { ...fields(c.querySelector('h4')), ...fields(c.querySelector('table.kv')) },
      contacts: [...c.querySelectorAll('tr[data-contact]')].map(fields),
      joints: [...c.querySelectorAll('tr[data-joint]')].map(fields),
    }));
  });
  // What the page shows against GET inspect: every number to the 6 digits printed.
  const mismatches = (cards, j) => {
    const bad = [];
    for (const p of j.panels) {
      const c = cards.find((x) => x.panel === p.panel);
      if (!c) { bad.push(`panel ${p.panel}: no card`); continue; }
      if (c.fields.name !== p.name) bad.push(`panel ${p.panel} name: page ${c.fields.name}, API ${p.name}`);
      if (Number(c.fields.step) !== p.step) bad.push(`panel ${p.panel} step: page ${c.fields.step}, API ${p.step}`);
      for (const k of ['time', 'mass', 'inertia', 'position', 'orientation', 'velocity', 'angular_velocity', 'kinetic'])
        if (!sameNumbers(c.fields[k], p[k])) bad.push(`panel ${p.panel} ${k}: page "${c.fields[k]}", API ${JSON.stringify(p[k])}`);
      const rows = (page, api, numeric, text, what) => {
        if (page.length !== Math.min(api.length, 40)) bad.push(`panel ${p.panel}: ${page.length} ${what} rows, API ${api.length}`);
        page.forEach((r, i) => {
          for (const k of numeric) if (!sameNumbers(r[k], api[i][k])) bad.push(`panel ${p.panel} ${what} ${i} ${k}: page "${r[k]}", API ${JSON.stringify(api[i][k])}`);
          for (const k of text) if (r[k] !== String(api[i][k] ?? '-')) bad.push(`panel ${p.panel} ${what} ${i} ${k}: page "${r[k]}", API ${api[i][k]}`);
        });
      };
      rows(c.contacts, p.contacts, ['point', 'normal', 'depth', 'normal_impulse', 'friction', 'twist'], ['other'], 'contact');
      rows(c.joints, p.joints, ['error', 'linear_impulse', 'angular_impulse'], ['name', 'kind', 'other'], 'joint');
    }
    return bad;
  };
  const inspectorAgrees = async (what) => {
    let bad = [];
    await until(`the inspector to agree with GET inspect (${what})`, async () => {
      const j = await api('/inspect');
      bad = mismatches(await readInspector(), j);
      return bad.length === 0 && j.body === (await page.textContent('#inspect-body')) && j;
    }, 10).catch(() => fail(`the inspector differs from GET inspect (${what}): ${bad.join('; ')}`));
    const j = await api('/inspect');
    check(true, `the inspector's numbers are GET inspect's (${what}: ${j.body} at step ${j.panels[0].step}, ` +
      `${j.panels[0].contacts.length} contacts, ${j.panels[0].joints.length} joints)`);
    return j;
  };

  // A pixel on a dynamic body (the API's pick), with its neighbours on the same body.
  const W = 640, H = 360;
  let hit = null;
  for (let y = 20; y < H - 10 && !hit; y += 8)
    for (let x = 10; x < W - 10 && !hit; x += 8) {
      const h = await post('/pick', { x, y });
      if (!h.hit) continue;
      const around = await Promise.all([[-2, 0], [2, 0], [0, -2], [0, 2]].map(([dx, dy]) => post('/pick', { x: x + dx, y: y + dy })));
      if (around.every((a) => a.hit && a.name === h.name)) hit = { ...h, x, y };
    }
  check(hit !== null, `a body under a pixel of the frame (${hit && hit.name} at ${hit && hit.x}, ${hit && hit.y})`);
  const vb = await (await page.$('#view')).boundingBox();
  await page.mouse.click(vb.x + (hit.x * vb.width) / W, vb.y + (hit.y * vb.height) / H);
  await until(`the inspector to show ${hit.name}`, async () => (await page.textContent('#inspect-body')) === hit.name);
  const selectedState = await api('');
  check(selectedState.selected === hit.name, `a click selects ${hit.name} (the state's "selected")`);
  check(!selectedState.playing && selectedState.timeline.shown_step === here.shown_step, 'a click neither plays nor moves the timeline');
  const j1 = await inspectorAgrees('clicked');
  check(j1.panels[0].step === selectedState.timeline.shown_step, 'GET inspect is at the shown step');
  await page.click('#step');
  const j2 = await until('the inspector at the next step', async () => {
    const j = await api('/inspect');
    return j.panels[0].step === j1.panels[0].step + 1 && Number(await page.textContent('.inspect-card [data-field=step]')) === j.panels[0].step && j;
  });
  await inspectorAgrees('one step on');
  check(JSON.stringify(j2.panels[0].velocity) !== JSON.stringify(j1.panels[0].velocity) ||
    JSON.stringify(j2.panels[0].position) !== JSON.stringify(j1.panels[0].position), 'and shows the body moved on');

  console.log('markers, jump to worst');
  const strip = await page.$$eval('#markers .marker', (ms) => ms.map((m) => ({ ...m.dataset })));
  const mk = strip[0];
  await page.dispatchEvent(`#markers .marker[data-step="${mk.step}"][data-kind="${mk.kind}"]`, 'click');
  await until(`the ${mk.kind} marker's step ${mk.step}`, async () => (await api('')).timeline.shown_step === Number(mk.step));
  if (mk.body) await until(`the marker's body ${mk.body} selected`, async () => (await api('')).selected === mk.body);
  check(true, `clicking a ${mk.kind} marker scrubs to its step ${mk.step}${mk.body ? ' and selects ' + mk.body : ''}`);
  const tlw = await api('/timeline');
  const worst = tlw.markers.filter((m) => m.kind === 'penetration').reduce((a, b) => (!a || b.value > a.value ? b : a), null);
  check(worst !== null, `a penetration marker (${worst && worst.text})`);
  await page.selectOption('#worst-kind', 'penetration');
  await page.click('#worst');
  await until('the worst penetration shown and its body selected', async () => {
    const s = await api('');
    return s.timeline.shown_step === worst.step && s.selected === worst.body && (await page.textContent('#inspect-body')) === worst.body;
  });
  check(true, `"jump to worst" shows step ${worst.step} (t = ${worst.time} s) with ${worst.body} selected`);
  const jw = await inspectorAgrees('worst penetration');
  check(jw.panels[0].contacts.length > 0, `the worst body has contacts there (${jw.panels[0].contacts.length})`);

  console.log('forces');
  const stillFrame = () => until('a still frame', async () => {
    const a = await frameSum();
    await sleep(600);
    return a !== null && a === (await frameSum()) && a;
  });
  // A step where the selected body's contacts carry an impulse, so that there is an arrow to draw.
  const pushing = (j) => j.panels[0].contacts.some((c) => c.normal_impulse > 0);
  for (let k = 0; k < 60 && !pushing(await api('/inspect')); ++k) {
    const at = (await api('')).timeline.shown_step;
    await page.click('#step');
    await until('the next step', async () => (await api('')).timeline.shown_step === at + 1);
  }
  const jf = await api('/inspect');
  check(pushing(jf), `at step ${jf.panels[0].step} ${jf.body} has contact impulses (λn up to ${Math.max(...jf.panels[0].contacts.map((c) => c.normal_impulse)).toPrecision(3)} N s)`);
  const noForces = await stillFrame();
  await page.check('#forces');
  await until('forces on', async () => (await api('')).view.forces === true);
  await until('the force arrows in the frame', async () => (await frameSum()) !== noForces);
  check(true, 'turning on "forces" changes the frame (contact and friction impulses drawn)');
  const withForces = await stillFrame();
  await page.check('#joint_errors');
  await until('joint errors on', async () => (await api('')).view.joint_errors === true);
  check(true, 'the "joint errors" toggle reaches the view');
  await page.uncheck('#forces');
  await until('forces off', async () => (await api('')).view.forces === false);
  await until('the frame without force arrows', async () => (await frameSum()) !== withForces);
  check(true, 'turning "forces" off changes the frame back');
  await page.check('#forces');
  await until('forces on again', async () => (await api('')).view.forces === true);
  await sleep(1500);  // the frame and the plots' cursor settle for the screenshot
  const shotTimeline = path.join(out, 'browser_timeline.png');
  await page.screenshot({ path: shotTimeline, fullPage: true });
  check(fs.statSync(shotTimeline).size > 10000, `screenshot saved: ${shotTimeline}`);

  console.log('recordings');
  const rec = path.join(out, 'browser_ragdoll.rec');
  const made = spawnSync(substep, ['run', path.join(scenes, 'ragdoll.json'), '--seconds', '2', '--record', rec], { encoding: 'utf8' });
  check(made.status === 0 && fs.existsSync(rec), `substep run --record wrote ${rec}${made.status ? ': ' + made.stderr : ''}`);
  const oldSession = await sessionId();
  await page.setInputFiles('#rec-file', rec);
  const replay = await until('a session on the uploaded recording', async () => {
    if ((await sessionId()) === oldSession) return false;
    const s = await api('');
    return s.timeline && s.timeline.recorded && s;
  });
  check(replay.bodies.length === 14 && replay.bodies.every((b) => b.startsWith('ragdoll_0_')) && Math.abs(replay.timeline.last - 2) < 1e-6,
  `the uploaded recording replays (${replay.scene}: the ragdoll's 14 bodies, ${replay.timeline.first}-${replay.timeline.last} s)`);
  await until('the previous session closed', async () => (await fetch(`${base}/api/sessions/${oldSession}`)).status === 404, 10);
check(true, 'the page closed its previous session');
  const recName = new URL(page.url()).searchParams.get('recording');
  await until(`${recName} in the page's list of recordings`, async () => (await page.$$eval('#recordings a', (as) => as.map((a) => a.textContent))).includes(recName));
  check(true, `the page lists ${recName} (GET /api/recordings)`);

  console.log('an atlas-style link: ?recording=&time=&body=');
  const linkBody = replay.bodies[Math.min(3, replay.bodies.length - 1)];
  await page.goto(`${base}/?recording=${encodeURIComponent(recName)}&time=1&body=${encodeURIComponent(linkBody)}`);
  const linked = await until('the linked step and body', async () => {
    const id = await sessionId();
    if (!id) return false;
    const s = await api('');
    return s.timeline && s.timeline.recorded && !s.playing && s.selected === linkBody &&
      s.timeline.shown <= 1 + 1e-9 && s.timeline.shown > 1 - s.timeline.dt - 1e-9 && s;
  });
  check(true, `the link opens ${recName} at t = ${linked.timeline.shown} s, paused, with ${linkBody} selected`);
  await inspectorAgrees('the link');

console.log("the atlas's inspect link: ?recordings=&focus=0");
await page.goto(`${base}/?recordings=${encodeURIComponent(recName)}&focus=0`);
const focused = await until('the recording at its focus', async () => {
  const id = await sessionId();
  if (!id) return false;
  const s = await api('');
  const body = (await page.textContent('#inspect-body')) || '';
  return s.timeline && s.timeline.recorded && s.selected && body === s.selected &&
    (await page.textContent('#shown-time')) === `t = ${s.timeline.shown.toFixed(3)} s` && s;
});
await sleep(1000);
const still = await api('');
check(!still.playing && still.timeline.shown === focused.timeline.shown,
  `the page stays at the focus (t = ${focused.timeline.shown.toFixed(3)} s, ${focused.selected} selected), paused`);
await inspectorAgrees('focus');

  console.log('serve --open');
  const server2 = spawn(substep, ['serve', '--port', '0', '--size', '320x180', '--open', rec], { stdio: ['ignore', 'pipe', 'pipe'] });
  let server2Out = '';
  server2.stdout.on('data', (d) => { server2Out += d; });
  server2.stderr.on('data', (d) => { server2Out += d; });
  const exited2 = new Promise((r) => server2.on('exit', (code) => r(code)));
  try {
    const port2 = await until('the second server', () => { const m = server2Out.match(/http:\/\/127\.0\.0\.1:(\d+)\//); return m && Number(m[1]); });
    const open = (await (await fetch(`http://127.0.0.1:${port2}/api/server`)).json()).open;
    check(Array.isArray(open) && open.length === 1, `GET /api/server lists the recording given by --open (${open})`);
    await page.goto(`http://127.0.0.1:${port2}/`);
    const opened = await until('the page on the --open recording', async () => {
      const id = await sessionId();
      if (!id) return false;
      const s = await (await fetch(`http://127.0.0.1:${port2}/api/sessions/${id}`)).json();
      return s.timeline && s.timeline.recorded && s;
    });
    check(opened.bodies.length === 14 && opened.bodies.every((b) => b.startsWith('ragdoll_0_')),
    `the page opens the --open recording (${opened.scene}) instead of its default scene`);
    await page.goto('about:blank');
  } finally {
    server2.kill('SIGINT');
    const code2 = await exited2;
    check(code2 === 130, `the second server stops on SIGINT (${code2})`);
  }

  check(errors.length === 0, `no errors in the page${errors.length ? ': ' + errors.join('; ') : ''}`);
} catch (e) {
  if (!process.exitCode) {
    console.error(`browser test: FAILED: ${e.stack || e}`);
    process.exitCode = 1;
  }
} finally {
  if (context) await context.close().catch(() => {});
  fs.rmSync(userDataDir, { recursive: true, force: true });
  server.kill('SIGINT');
  const timer = setTimeout(() => server.kill('SIGKILL'), 15000);
  const { code } = await exited;
  clearTimeout(timer);
  if (code !== 130) {
    console.error(`browser test: FAILED: the server exited with ${code} after SIGINT, not 130\n${serverOut}`);
    process.exitCode = 1;
  } else {
    console.log('  ok: SIGINT stops the server (exit status 130)');
  }
  console.log(process.exitCode ? 'browser test: FAILED' : 'browser test: passed');
}
