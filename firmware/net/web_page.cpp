#include "firmware/net/web_page.hpp"

namespace calbox::firmware {

// The page's three texts, served as they are written here.
constexpr std::string_view kPageHtml = R"html(<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>calbox</title>
<link rel="stylesheet" href="/style.css">
<script src="/app.js" defer></script>
</head>
<body>
<header>
  <h1>calbox</h1>
  <span id="state" class="badge">…</span>
  <span id="link" class="muted">connecting</span>
  <label class="password">Web password <input id="password" type="password" autocomplete="current-password"></label>
</header>
<nav>
  <button data-view="status" class="tab on">Status</button>
  <button data-view="setup" class="tab">Set-up</button>
  <button data-view="result" class="tab">Result</button>
  <button data-view="place" class="tab">Place</button>
  <button data-view="config" class="tab">Configuration</button>
</nav>
<main>
<section id="view-status" class="view">
  <div class="card">
    <p class="big">Waiting for: <b id="waiting">nothing</b></p>
    <p>Cycle <span id="cycle">0</span> (<span id="completed">0</span> completed since start) · mode <span id="mode">–</span></p>
    <p id="error" class="error"></p>
    <div class="actions">
      <button id="btn-start">Start</button>
      <button id="btn-confirm">Confirm</button>
      <button id="btn-cancel">Cancel</button>
      <button id="btn-acknowledge">Acknowledge</button>
      <button id="btn-revert">Revert</button>
    </div>
    <p><span id="action-reply" class="muted"></span></p>
  </div>
  <div class="card">
    <h2>Machine</h2>
    <p>Last error before correction: <b id="last-before">–</b> · after: <b id="last-after">–</b></p>
    <p>Drift since the last calibration: <b id="drift">–</b> · calibrated <span id="calibrated">never</span></p>
    <p id="needs" class="muted"></p>
    <h2>Drift history</h2>
    <svg id="history" viewBox="0 0 600 160" role="img" aria-label="each cycle's error before and after its correction"></svg>
    <p class="muted"><span class="key before"></span> before correction <span class="key after"></span> after</p>
  </div>
  <div class="card wide">
    <h2>Log</h2>
    <pre id="log"></pre>
  </div>
</section>
<section id="view-setup" class="view" hidden>
  <div class="card wide">
    <h2>Live view</h2>
    <img id="live" alt="the camera's live view">
    <p class="muted">Frame <span id="frame">–</span> · sharpness <b id="sharpness">–</b> (turn the focus for the highest)</p>
  </div>
</section>
<section id="view-result" class="view" hidden>
  <div class="card wide">
    <h2>Last cycle</h2>
    <table id="result"><tbody></tbody></table>
    <div id="pictures"></div>
  </div>
  <div class="card wide">
    <h2>Jobs through the correction</h2>
    <p class="muted">A job in the box's data directory (job-NAME.gcode, .nc, .ngc, .tap, .g, .csv) sent through the correction the box keeps, placed at its work zero: X,Y (machine coordinates), measured (the frame the correction was measured in), controller (grbl's offsets, read over the link; what an empty field means on grbl) or G54=X,Y G55=X,Y. The compensated job appears in the records as job-NAME-compensated.</p>
    <p><label>Job <input id="job-name" placeholder="job-part.nc"></label>
      <label>Work zero <input id="job-zero" placeholder="controller"></label>
      <button id="btn-compensate">Compensate</button> <span id="job-reply" class="muted"></span></p>
  </div>
  <div class="card wide">
    <h2>Records</h2>
    <ul id="records"></ul>
  </div>
</section>
<section id="view-place" class="view" hidden>
  <div class="card wide">
    <h2>Place a job on the bed</h2>
    <p class="muted">The bed as the box's camera sees it, in the machine's coordinates (as a job compensated through the correction in force means them). Choose a job from the data directory and click where its work zero (G54's origin) goes, or, when the bed photo found a sheet, give camera (its corner nearest the machine's zero; camera front-right names another), or, for print and cut, give the printed drawing's marks (their centres in the drawing, X,Y each) before photographing the bed and place the job by marks: the job is drawn where the tool will go, before anything runs. Compensate writes it through the correction, ready to download; the controller's own zero is yours to set there.</p>
    <p><label>Job <select id="place-job"></select></label>
      <label>Work zero <input id="place-zero" placeholder="click the bed, X,Y, camera or marks"></label>
      <button id="btn-place">Compensate</button> <button id="btn-zero">Set the controller's zero here</button>
      <span id="place-reply" class="muted"></span></p>
    <p><button id="btn-bed-photo">Photograph the bed</button>
      <label>its surface (the stock's top) <input id="bed-surface" size="6" placeholder="machine file's"> mm above the bed</label>
      <label>printed marks <input id="bed-marks" size="30" placeholder="X,Y X,Y X,Y [X,Y] in the drawing"></label>
      <span id="bed-reply" class="muted"></span></p>
    <p id="place-frame" class="muted"></p>
    <div id="place-bed"><img id="bed" alt="the bed in the machine's coordinates"><svg id="bed-job" preserveAspectRatio="none" role="img" aria-label="the job where its tool will go"></svg></div>
    <p id="bed-caption" class="muted"></p>
    <p id="place-download"></p>
  </div>
</section>
<section id="view-config" class="view" hidden>
  <div class="card wide">
    <h2>Configuration</h2>
    <p class="muted">The console's keys, checked as the console checks them. Changes need the web password; Save keeps them.</p>
    <table id="config"><tbody></tbody></table>
    <button id="btn-save">Save</button> <span id="config-reply" class="muted"></span>
  </div>
</section>
</main>
</body>
</html>
)html";

constexpr std::string_view kPageScript = R"js('use strict';
const $ = (id) => document.getElementById(id);
const mm = (v) => (v === null || v === undefined) ? '–' : v.toFixed(4) + ' mm';
const headline = (f) => f ? (f.mean_mm !== null ? f.mean_mm : f.rms_mm) : null;
let status = null;
let shownCycle = -1;

function auth() {
  return {'Content-Type': 'application/json',
          'Authorization': 'Basic ' + btoa('calbox:' + $('password').value)};
}
async function send(path, body, replyId) {
  sessionStorage.setItem('calbox-password', $('password').value);
  const r = await fetch(path, {method: 'POST', headers: auth(), body: JSON.stringify(body)});
  const j = await r.json().catch(() => ({error: r.statusText}));
  $(replyId).textContent = r.ok ? 'done' : (r.status + ': ' + j.error);
  $(replyId).className = r.ok ? 'muted' : 'error';
  return r.ok;
}

function showStatus(s) {
  status = s;
  $('state').textContent = s.state;
  $('state').className = 'badge ' + s.state;
  $('waiting').textContent = s.waiting || 'nothing';
  $('cycle').textContent = s.cycle;
  $('completed').textContent = s.completed;
  $('mode').textContent = s.mode;
  $('error').textContent = s.error ? 'Last error: ' + s.error : '';
  const last = s.last;
  $('last-before').textContent = last ? mm(headline(last.before)) : '–';
  $('last-after').textContent = last ? mm(headline(last.after)) : '–';
  $('drift').textContent = mm(s.drift_mm);
  $('calibrated').textContent = s.last_calibrated || 'never';
  $('needs').textContent = s.needs_calibration === null ? '' :
      (s.needs_calibration ? 'Needs calibrating: the error jobs met at the last cycle is over '
                            : 'Within the limit of ') + s.needs_calibration_mm + ' mm';
  if (s.log) {
    // The newest line in view, unless the reader has scrolled up to read an older one.
    const log = $('log');
    const atEnd = log.scrollTop + log.clientHeight >= log.scrollHeight - 4;
    log.textContent = s.log.join('\n');
    if (atEnd || !log.dataset.seen) log.scrollTop = log.scrollHeight;
    log.dataset.seen = '1';
  }
  const ids = {start: s.state === 'idle', confirm: !!s.waiting && s.state !== 'idle',
               cancel: s.state !== 'idle', acknowledge: s.state === 'error', revert: s.state === 'idle'};
  for (const [k, on] of Object.entries(ids)) $('btn-' + k).disabled = !on;
  if (last && last.cycle !== shownCycle) { shownCycle = last.cycle; showResult(last); }
  if (s.history) drawHistory(s.history);
}

function drawHistory(cycles) {
  const svg = $('history');
  const pts = cycles.filter((c) => c.before || c.after);
  const w = 600, h = 160, pad = 30;
  const top = Math.max(0.001, ...pts.flatMap((c) => [headline(c.before) || 0, headline(c.after) || 0]));
  const x = (i) => pad + (pts.length < 2 ? (w - 2 * pad) / 2 : i * (w - 2 * pad) / (pts.length - 1));
  const y = (v) => h - pad - v / top * (h - 2 * pad);
  let out = `<line x1="${pad}" y1="${h - pad}" x2="${w - pad}" y2="${h - pad}" class="axis"/>` +
            `<text x="2" y="${pad - 8}" class="label">${top.toFixed(3)} mm</text>` +
            `<text x="2" y="${h - pad + 4}" class="label">0</text>`;
  for (const [key, cls] of [['before', 'before'], ['after', 'after']]) {
    const line = pts.map((c, i) => [i, headline(c[key])]).filter((p) => p[1] !== null);
    if (line.length > 1)
      out += `<polyline class="${cls}" points="${line.map((p) => x(p[0]) + ',' + y(p[1])).join(' ')}"/>`;
    for (const p of line) out += `<circle class="${cls}" cx="${x(p[0])}" cy="${y(p[1])}" r="3"><title>cycle ${pts[p[0]].cycle}, ${pts[p[0]].finished}: ${p[1].toFixed(4)} mm</title></circle>`;
  }
  svg.innerHTML = out;
}

function showResult(last) {
  const rows = [['Cycle', last.cycle], ['Mode', last.mode], ['Result', last.result], ['Finished', last.finished],
                ['Before: mean', mm(last.before && last.before.mean_mm)], ['Before: RMS', mm(last.before && last.before.rms_mm)],
                ['Before: worst', mm(last.before && last.before.max_mm)], ['After: mean', mm(last.after && last.after.mean_mm)],
                ['After: RMS', mm(last.after && last.after.rms_mm)], ['After: worst', mm(last.after && last.after.max_mm)],
                ['Time', last.seconds.toFixed(1) + ' s']];
  const body = $('result').tBodies[0];
  body.replaceChildren(...rows.map(([k, v]) => {
    const tr = document.createElement('tr');
    tr.innerHTML = `<th></th><td></td>`;
    tr.cells[0].textContent = k; tr.cells[1].textContent = v;
    tr.id = 'result-' + k.toLowerCase().replace(/[^a-z]+/g, '-');
    return tr;
  }));
  loadRecords(last.cycle);
}

async function loadRecords(cycle) {
  const r = await fetch('/records/');
  if (!r.ok) return;
  const list = (await r.json()).records;
  $('records').replaceChildren(...list.map((e) => {
    const li = document.createElement('li');
    const a = document.createElement('a');
    a.href = '/records/' + encodeURIComponent(e.name) + '?download=1';
    a.textContent = e.name;
    li.append(a, ` (${e.bytes} bytes)`);
    return li;
  }));
  const prefix = 'cycle-' + String(cycle).padStart(4, '0') + '-';
  const pictures = list.filter((e) => e.name.startsWith(prefix) && e.name.endsWith('.png') && !e.name.includes('-photo-'));
  $('pictures').replaceChildren(...pictures.map((e) => {
    const fig = document.createElement('figure');
    const img = document.createElement('img');
    img.src = '/records/' + encodeURIComponent(e.name);
    img.alt = e.name;
    const cap = document.createElement('figcaption');
    cap.textContent = e.name;
    fig.append(img, cap);
    fig.className = e.name.includes('screen-') ? 'screen' : 'picture';
    return fig;
  }));
}

// The bed view's world file: machine X = c + a (column), Y = f + e (row), at pixel centres.
let bed = null;
const jobExt = /^job-[A-Za-z0-9._-]+\.(gcode|nc|ngc|tap|g|csv|txt)$/;
async function loadPlace() {
  const r = await fetch('/records/');
  if (!r.ok) return;
  const names = (await r.json()).records.map((e) => e.name);
  const chosen = $('place-job').value;
  const jobs = names.filter((n) => jobExt.test(n) && !/-compensated\.[a-z]+$/.test(n));
  $('place-job').replaceChildren(...jobs.map((n) => {
    const o = document.createElement('option');
    o.value = o.textContent = n;
    o.selected = n === chosen;
    return o;
  }));
  // A photo of the bed as it is now when the box has one, else the last cycle's.
  const name = names.includes('bed-view.png') ? 'bed-view.png'
      : names.filter((n) => /^cycle-\d{4}-bed-view\.png$/.test(n)).sort().pop();
  if (!name) { $('bed-caption').textContent = 'No bed view yet: a planar cycle keeps one.'; return; }
  const w = await fetch('/records/' + name.replace(/\.png$/, '.pgw'));
  if (!w.ok) { $('bed-caption').textContent = name + ': its world file is missing.'; return; }
  const [a, , , e, c, f] = (await w.text()).trim().split(/\s+/).map(Number);
  const img = $('bed');
  img.onload = () => {
    bed = {name, a, e, c, f, width: img.naturalWidth, height: img.naturalHeight};
    $('bed-job').setAttribute('viewBox', `0 0 ${bed.width} ${bed.height}`);
    $('bed-caption').textContent = `${name}: ${a} mm a pixel; its top-left pixel's centre at machine X${c} Y${f}.`;
    drawJob();
  };
  img.src = '/records/' + encodeURIComponent(name) + '?v=' + Date.now();
}
function pixelOf(x, y) { return [(x - bed.c) / bed.a + 0.5, (y - bed.f) / bed.e + 0.5]; }
let drawn = 0;
async function drawJob() {
  const svg = $('bed-job');
  const job = $('place-job').value, zero = $('place-zero').value.trim();
  if (!bed || !job) { svg.innerHTML = ''; return; }
  const ticket = ++drawn;
  const r = await fetch('/api/place?job=' + encodeURIComponent(job) + '&work_zero=' + encodeURIComponent(zero));
  const j = await r.json().catch(() => ({error: r.statusText}));
  if (ticket !== drawn) return;
  if (!r.ok) { svg.innerHTML = ''; $('place-frame').textContent = j.error; $('place-frame').className = 'error'; return; }
  $('place-frame').textContent = j.summary + '; ' + j.frame;
  $('place-frame').className = 'muted';
  const pts = j.points.map((p) => pixelOf(p[0], p[1]).map((v) => v.toFixed(2)).join(',')).join(' ');
  let out = `<polyline id="bed-job-path" points="${pts}"/>`;
  const m = /^\s*(-?[0-9.]+)\s*,\s*(-?[0-9.]+)\s*$/.exec(zero);
  if (m) {
    const [x, y] = pixelOf(Number(m[1]), Number(m[2]));
    out += `<circle id="bed-zero" cx="${x}" cy="${y}" r="6"/><line x1="${x - 12}" y1="${y}" x2="${x + 12}" y2="${y}"/>` +
           `<line x1="${x}" y1="${y - 12}" x2="${x}" y2="${y + 12}"/>`;
  }
  svg.innerHTML = out;
}
function placeClick(ev) {
  if (!bed) return;
  const rect = $('bed').getBoundingClientRect();
  const col = (ev.clientX - rect.left) * bed.width / rect.width - 0.5;
  const row = (ev.clientY - rect.top) * bed.height / rect.height - 0.5;
  $('place-zero').value = (bed.c + bed.a * col).toFixed(3) + ',' + (bed.f + bed.e * row).toFixed(3);
  drawJob();
}
// The desks work in the background and say how it went in the log: the page waits for a new
// line of theirs after sending the action; null when none came.
async function sendAndHear(body, prefix, replyId) {
  const said = (s) => (s.log || []).filter((l) => l.startsWith(prefix));
  const before = said(await (await fetch('/api/status')).json()).length;
  if (!await send('/api/action', body, replyId)) return null;
  $(replyId).textContent = 'working…';
  for (let i = 0; i < 240; ++i) {
    await new Promise((ok) => setTimeout(ok, 500));
    const lines = said(await (await fetch('/api/status')).json());
    if (lines.length > before) return lines[lines.length - 1];
  }
  $(replyId).textContent = 'the box did not say how it went';
  $(replyId).className = 'error';
  return null;
}
async function bedPhoto() {
  const body = {action: 'bed-photo'};
  if ($('bed-surface').value.trim() !== '') body.surface_mm = Number($('bed-surface').value);
  if ($('bed-marks').value.trim() !== '') body.marks = $('bed-marks').value.trim();
  const line = await sendAndHear(body, 'bed photo: ', 'bed-reply');
  if (line === null) return;
  $('bed-reply').textContent = line;
  $('bed-reply').className = line.includes('nothing written') || line.includes('no marks placed') ? 'error' : 'muted';
  // A drawing's marks or a sheet found: the job goes by them unless the owner points elsewhere.
  if (line.includes("the drawing's marks found")) $('place-zero').value = 'marks';
  else if (line.includes('the sheet found')) $('place-zero').value = 'camera';
  loadPlace();
}
// The controller's G54 moves only after the owner has read what will be sent and said yes.
async function placeZero() {
  const zero = $('place-zero').value.trim();
  const r = await fetch('/api/action', {method: 'POST', headers: auth(),
                                        body: JSON.stringify({action: 'work-zero', work_zero: zero})});
  const j = await r.json().catch(() => ({error: r.statusText}));
  if (!r.ok) { $('place-reply').textContent = r.status + ': ' + j.error; $('place-reply').className = 'error'; return; }
  if (!window.confirm('Send ' + j.command + ' to the controller? Its G54 zero moves there.')) return;
  const line = await sendAndHear({action: 'work-zero', work_zero: zero, confirm: true}, 'work zero: ', 'place-reply');
  if (line === null) return;
  $('place-reply').textContent = line;
  $('place-reply').className = line.includes('read back') ? 'muted' : 'error';
}
async function placeCompensate() {
  const job = $('place-job').value;
  const out = job.replace(/(\.[A-Za-z]+)$/, '-compensated$1');
  $('place-download').replaceChildren();
  const line = await sendAndHear({action: 'compensate', job, work_zero: $('place-zero').value.trim()},
                                 'compensate: ', 'place-reply');
  if (line !== null) {
    const written = line.startsWith('compensate: ' + out + ': ');
    $('place-reply').textContent = line;
    $('place-reply').className = written ? 'muted' : 'error';
    if (written) {
      const a = document.createElement('a');
      a.id = 'place-download-link';
      a.href = '/records/' + encodeURIComponent(out) + '?download=1';
      a.textContent = 'Download ' + out;
      $('place-download').replaceChildren(a);
    }
  }
}

async function refresh() {
  const r = await fetch('/api/status');
  if (r.ok) showStatus(await r.json());
}

function listen() {
  const ws = new WebSocket((location.protocol === 'https:' ? 'wss://' : 'ws://') + location.host + '/events');
  ws.onopen = () => { $('link').textContent = 'live'; refresh(); };
  ws.onmessage = (m) => {
    const e = JSON.parse(m.data);
    if (e.type === 'status') showStatus(e.status);
  };
  ws.onclose = () => { $('link').textContent = 'reconnecting'; setTimeout(listen, 2000); };
}

let frame = 0;
async function liveLoop() {
  for (;;) {
    if ($('view-setup').hidden) { await new Promise((ok) => setTimeout(ok, 500)); continue; }
    try {
      const r = await fetch('/live.jpg?after=' + frame);
      if (r.ok) {
        frame = Number(r.headers.get('X-Frame'));
        $('frame').textContent = frame;
        $('sharpness').textContent = r.headers.get('X-Sharpness');
        const old = $('live').src;
        $('live').src = URL.createObjectURL(await r.blob());
        if (old.startsWith('blob:')) URL.revokeObjectURL(old);
        // A few frames a second aim and focus a box; more would only load it.
        await new Promise((ok) => setTimeout(ok, 250));
      } else {
        await new Promise((ok) => setTimeout(ok, 1000));
      }
    } catch (e) {
      await new Promise((ok) => setTimeout(ok, 1000));
    }
  }
}

async function loadConfig() {
  const r = await fetch('/api/config');
  if (!r.ok) return;
  const j = await r.json();
  const body = $('config').tBodies[0];
  body.replaceChildren(...Object.entries(j.config).map(([key, k]) => {
    const tr = document.createElement('tr');
    tr.innerHTML = '<th></th><td><input></td><td class="muted"></td>';
    tr.cells[0].textContent = key;
    const input = tr.querySelector('input');
    input.value = k.value;
    input.id = 'config-' + key;
    input.onchange = async () => {
      if (!await send('/api/config', {key, value: input.value}, 'config-reply')) input.value = k.value;
      else k.value = input.value;
    };
    tr.cells[2].textContent = (k.unit ? k.unit + ' · ' : '') + k.doc + (k.at_start ? ' [at start]' : '');
    return tr;
  }));
}

document.addEventListener('DOMContentLoaded', () => {
  $('password').value = sessionStorage.getItem('calbox-password') || '';
  for (const a of ['start', 'confirm', 'cancel', 'acknowledge', 'revert'])
    $('btn-' + a).onclick = () => send('/api/action', {action: a}, 'action-reply');
  $('btn-save').onclick = () => send('/api/config', {save: true}, 'config-reply');
  $('btn-compensate').onclick = () => send('/api/action',
    {action: 'compensate', job: $('job-name').value, work_zero: $('job-zero').value}, 'job-reply');
  $('bed').onclick = placeClick;
  $('bed-job').onclick = placeClick;
  $('place-job').onchange = drawJob;
  $('place-zero').onchange = drawJob;
  $('btn-place').onclick = placeCompensate;
  $('btn-bed-photo').onclick = bedPhoto;
  $('btn-zero').onclick = placeZero;
  for (const tab of document.querySelectorAll('nav .tab')) {
    tab.onclick = () => {
      for (const t of document.querySelectorAll('nav .tab')) t.classList.toggle('on', t === tab);
      for (const v of document.querySelectorAll('.view')) v.hidden = v.id !== 'view-' + tab.dataset.view;
      if (tab.dataset.view === 'config') loadConfig();
      if (tab.dataset.view === 'place') loadPlace();
      if (tab.dataset.view === 'result' && status && status.last) loadRecords(status.last.cycle);
    };
  }
  refresh();
  listen();
  liveLoop();
});
)js";

constexpr std::string_view kPageStyle = R"css(* { box-sizing: border-box; }
body { font-family: sans-serif; margin: 0; background: #f4f5f7; color: #1d2330; }
header { display: flex; gap: 1em; align-items: center; padding: 0.6em 1em; background: #1d2330; color: #fff; }
header h1 { font-size: 1.3em; margin: 0; }
header .password { margin-left: auto; font-size: 0.9em; }
nav { display: flex; gap: 0.3em; padding: 0.5em 1em; }
.tab { border: 0; padding: 0.5em 1em; background: #dde1e8; border-radius: 4px; cursor: pointer; }
.tab.on { background: #2d6cdf; color: #fff; }
main { padding: 0 1em 1em; }
.view { display: flex; flex-wrap: wrap; gap: 1em; }
.view[hidden] { display: none; }
.card { background: #fff; border-radius: 6px; padding: 0.8em 1.2em; flex: 1 1 22em; box-shadow: 0 1px 3px #0002; }
.card.wide { flex-basis: 100%; }
h2 { font-size: 1.05em; margin: 0.6em 0 0.4em; }
.big { font-size: 1.2em; }
.badge { padding: 0.2em 0.6em; border-radius: 4px; background: #556; }
.badge.idle { background: #2f8f4e; } .badge.error { background: #c0392b; } .badge.review { background: #d68910; }
.muted { color: #667; } .error { color: #c0392b; }
.actions button, #btn-save { padding: 0.5em 1.1em; margin: 0.2em 0.3em 0.2em 0; font-size: 1em; }
pre { max-height: 18em; overflow: auto; white-space: pre-wrap; background: #f0f1f4; padding: 0.5em; font-size: 0.85em; }
#live { max-width: 100%; background: #000; min-height: 10em; }
svg { width: 100%; max-width: 600px; height: auto; background: #fafbfc; }
svg .axis { stroke: #889; } svg .label { font-size: 11px; fill: #667; }
svg polyline { fill: none; stroke-width: 2; }
svg .before { stroke: #c0392b; fill: #c0392b; } svg .after { stroke: #2f8f4e; fill: #2f8f4e; }
svg polyline.before, svg polyline.after { fill: none; }
.key { display: inline-block; width: 1em; height: 0.6em; }
.key.before { background: #c0392b; } .key.after { background: #2f8f4e; }
table { border-collapse: collapse; } th { text-align: left; padding-right: 1em; font-weight: normal; color: #445; }
td, th { padding: 0.2em 0.6em 0.2em 0; vertical-align: top; }
#config input { width: 16em; }
#pictures { display: flex; flex-wrap: wrap; gap: 1em; }
figure { margin: 0; } figure.picture img { max-width: 100%; width: 640px; }
figure.screen img { width: 256px; image-rendering: pixelated; border: 1px solid #889; }
figcaption { font-size: 0.8em; color: #667; }
#place-bed { position: relative; display: inline-block; max-width: 100%; }
#bed { display: block; max-width: 100%; cursor: crosshair; }
#bed-job { position: absolute; left: 0; top: 0; width: 100%; height: 100%; max-width: none; background: none; cursor: crosshair; }
#bed-job polyline { fill: none; stroke: #e8590c; stroke-width: 1.5; vector-effect: non-scaling-stroke; }
#bed-job circle { fill: none; stroke: #2d6cdf; stroke-width: 2; vector-effect: non-scaling-stroke; }
#bed-job line { stroke: #2d6cdf; stroke-width: 1.5; vector-effect: non-scaling-stroke; }
)css";

std::string_view web_page_html() {
    return kPageHtml;
}
std::string_view web_page_script() {
    return kPageScript;
}
std::string_view web_page_style() {
    return kPageStyle;
}

}  // namespace calbox::firmware
