// The browser test of `substep serve` (CTest `browser_page`): Debian's chromium, headless, driven by
// playwright-core from npm (installed by scripts/test into the build folder; no browser download).
// It does what a user does: opens the page, starts a scene, watches the stream change and the
// stats arrive, switches the method, pushes a body and sees it move, opens the side-by-side view,
// downloads a PNG, and saves a screenshot.
//
//   node browser_test.mjs --substep build/app/substep --out build/browser [--chromium /usr/bin/chromium]
import { spawn } from 'node:child_process';
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
  page.on('console', (m) => { if (m.type() === 'error' && !/favicon/.test(m.text())) errors.push(m.text()); });

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
  const box = await page.$('#view');
  const bb = await box.boundingBox();
  await page.mouse.click(bb.x + bb.width / 2, bb.y + bb.height / 2);
  await until('"pushed box"', async () => /pushed box/.test(await page.textContent('#message')));
  check(true, 'a click on the box pushes it');
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
