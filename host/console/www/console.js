// console.js - the RBX1 web console's behaviour: requests to rbx1d's /api, the event stream, the pictures.
'use strict';

const $ = (id) => document.getElementById(id);
// This page's name for the daemon: its jogs last while this page's event stream is open (the dead-man rule).
const pageId = Array.from(crypto.getRandomValues(new Uint8Array(16)), (b) => b.toString(16).padStart(2, '0')).join('');
const state = { token: localStorage.getItem('rbx1.token') || '', detections: null, selected: null,
                events: null, statusBusy: false, lastScan: -1 };

// ---- requests -----------------------------------------------------------------------------------------------
function headers(json) {
  const h = json ? { 'Content-Type': 'application/json', 'X-RBX1-Page': pageId } : {};
  if (state.token) h.Authorization = 'Bearer ' + state.token;
  return h;
}
function withToken(url) {
  return state.token ? url + (url.includes('?') ? '&' : '?') + 'token=' + encodeURIComponent(state.token) : url;
}
function say(text, kind) {
  const m = $('message');
  m.textContent = text;
  m.className = kind || '';
}
// Requests that end when the page goes away (a jog's dead-man rule: its connection closes, the daemon stops it).
const leaving = new AbortController();
window.addEventListener('pagehide', () => leaving.abort());
// POST /api/CMD with body; resolves to the daemon's final line ({result} or {error}) with its events, or for a sort
// or clear that started, {started, req} (202).
async function call(cmd, body) {
  let reply;
  try {
    const r = await fetch('/api/' + cmd, { method: 'POST', headers: headers(true), body: JSON.stringify(body || {}),
                                          signal: cmd === 'jog' ? leaving.signal : undefined });
    reply = await r.json();
  } catch (e) {
    reply = { error: { code: 'unreachable', message: 'rbx1d did not answer: ' + e } };
  }
  if (reply.error && reply.error.code === 'estop') return reply;  // the e-stop's own message (estop.js) stays
  if (reply.error) say(cmd + ': ' + reply.error.code + ': ' + reply.error.message, 'error');
  else if (reply.started) say(cmd + ': started (job ' + reply.started.job + '): its progress below', 'ok');
  else say(cmd + ': done', 'ok');
  return reply;
}
// Buttons that start a request are disabled until its reply (the e-stop never is).
function action(id, fn) {
  $(id).addEventListener('click', async () => {
    const b = $(id);
    b.disabled = true;
    try { await fn(); } finally { b.disabled = false; }
  });
}

// ---- arm state ----------------------------------------------------------------------------------------------
function fmt(v) {
  if (v === null || v === undefined) return '–';
  if (Array.isArray(v)) return v.map(fmt).join(', ');
  if (typeof v === 'object') return Object.entries(v).map(([k, x]) => k + ' ' + fmt(x)).join(', ');
  return String(v);
}
function showPlaces(names) {
  const list = $('places');
  const have = [...list.options].map((o) => o.value).join('\n');
  if (have !== names.join('\n'))
    list.replaceChildren(...names.map((p) => Object.assign(document.createElement('option'), { value: p })));
}
// The homed mask in words: "all 6 joints", "J1, J3 of 6", "none".
function homedText(mask, joints) {
  if (mask === undefined || mask === null) return null;
  const n = joints || 6;
  const homed = [...Array(n).keys()].filter((i) => mask & (1 << i)).map((i) => 'J' + (i + 1));
  return homed.length === n ? 'all ' + n + ' joints' : homed.length ? homed.join(', ') + ' of ' + n : 'none';
}
// Firmware faults that stop nothing are notices with what to do, not red faults.
const NOTICES = { EEPROM_DEFAULTS: 'the board runs on its default settings (its EEPROM was empty or invalid); they are written once settings are set (CONFIG_SET), and Clear fault dismisses this' };
function showStatus(s) {
  const fw = s.firmware || {};
  if (s.places) showPlaces(s.places);
  const faults = (fw.faults || []).filter((f) => !NOTICES[f]);
  const notices = (fw.faults || []).filter((f) => NOTICES[f]).map((f) => NOTICES[f]);
  const faulted = fw.state === 'FAULT' || faults.length;
  const badge = $('state');
  badge.textContent = s.ready ? 'ready' : faulted ? 'fault' : 'not ready';
  badge.className = 'badge ' + (s.ready ? 'ok' : 'bad');
  $('job').textContent = s.job ? 'job: ' + s.job : '';
  $('job').className = 'badge quiet' + (s.job ? ' busy' : '');
  if (!s.job && job.running) {  // its end was missed (the event stream reconnected): the status has the last word
    Object.assign(job, { running: false, paused: false });
    jobButtons();
  }
  const rows = [['firmware', fw.state], ['faults', faults], ['notice', notices.length ? notices.join('; ') : null],
                ['homed', homedText(fw.homed, (s.joints_deg || []).length)], ['joints (°)', s.joints_deg],
                ['position (steps)', fw.position], ['gripper (µs)', fw.gripper_us],
                ['link', s.link && (s.link.connected ? 'up ' : 'down ') + (s.link.port || '') + (s.link.error ? ' – ' + s.link.error : '')],
                ['last e-stop', s.last_estop], ['camera', s.camera], ['calibration', calibrationText(s.calibration)]];
  const body = $('arm-state').tBodies[0];
  body.replaceChildren(...rows.map(([k, v]) => {
    const tr = document.createElement('tr');
    tr.innerHTML = '<td></td><td></td>';
    tr.cells[0].textContent = k;
    tr.cells[1].textContent = fmt(v);
    if (k === 'faults' && v && v.length) tr.cells[1].className = 'bad';
    return tr;
  }));
}
// The camera-to-arm map in force: the configured mount, or the workspace calibration with its own error.
function calibrationText(c) {
  if (!c) return null;
  if (c.in_force !== 'workspace') return 'mount ([arm.camera] of the config): no workspace calibration';
  return 'workspace: ' + c.model + ' over ' + c.markers + ' markers, RMS ' + num(c.rms_mm, 3) + ' mm, worst leave-one-out ' +
         num(c.max_loo_mm, 3) + ' mm' + (c.table_z_mm === null ? '' : ', table at z ' + num(c.table_z_mm, 2) + ' mm');
}
async function pollStatus() {
  if (state.statusBusy) return;
  state.statusBusy = true;
  try {
    const r = await fetch('/api/status', { headers: headers(false) });
    const j = await r.json();
    if (j.result) showStatus(j.result);
    else { $('state').textContent = j.error.code; $('state').className = 'badge bad'; }
  } catch (e) {
    $('state').textContent = 'rbx1d unreachable';
    $('state').className = 'badge bad';
  } finally {
    state.statusBusy = false;
  }
}

// ---- pictures and the objects (Figure 20, Figure 21) --------------------------------------------------------
function viewMode() { return document.querySelector('input[name=viewmode]:checked').value; }
// The picture is shown once it has loaded; until then, or when it cannot load, a line says why (never a broken
// image).
function showEmpty(text) {
  const img = $('view');
  img.hidden = true;
  img.removeAttribute('src');
  $('view-empty').textContent = text;
  $('view-empty').hidden = false;
}
function showView() {
  const img = $('view');
  if (viewMode() === 'live') {
    img.src = withToken('/api/live.mjpg');
    img.hidden = false;  // a live stream may not fire load before its first frame is replaced
    $('view-empty').hidden = true;
  } else if (state.lastScan > 0) {
    img.src = withToken('/api/scan.jpg?n=' + state.lastScan);
  } else {
    showEmpty('no scan yet: press Scan');
  }
}
$('view').addEventListener('load', () => {
  $('view').hidden = false;
  $('view-empty').hidden = true;
});
$('view').addEventListener('error', () => {
  if (!$('view').getAttribute('src')) return;
  showEmpty(viewMode() === 'live' ? 'no live view: the camera or rbx1d did not answer (see the camera row)'
                                  : 'the last scan\'s image could not be loaded (see the message above)');
});
document.querySelectorAll('input[name=viewmode]').forEach((r) => r.addEventListener('change', showView));

function num(v, digits) { return v === null || v === undefined ? '–' : Number(v).toFixed(digits); }
function showObjects() {
  const objs = (state.detections && state.detections.objects) || [];
  const body = $('objects').tBodies[0];
  body.replaceChildren(...objs.map((o) => {
    const tr = document.createElement('tr');
    tr.dataset.index = o.index;
    const g = o.grip || {};
    const cells = [o.index, o.label || 'unknown', num(o.match_score, 2),
                   o.centroid_cm ? num(o.centroid_cm[0], 2) + ', ' + num(o.centroid_cm[1], 2) : '–',
                   num(g.opening_cm, 2), num(g.angle_deg, 2), g.feasible ? 'ok' : (g.reason || 'not pickable')];
    for (const c of cells) {
      const td = document.createElement('td');
      td.textContent = c;
      tr.appendChild(td);
    }
    if (!g.feasible) tr.lastChild.className = 'bad';
    if (state.selected === o.index) tr.className = 'selected';
    tr.addEventListener('click', () => select(o.index));
    return tr;
  }));
  $('scan-info').textContent = objs.length + ' found';
}
function select(index) {
  state.selected = index;
  const o = ((state.detections && state.detections.objects) || []).find((x) => x.index === index);
  if (o && o.label) $('pick-name').value = o.label;
  showObjects();
  document.dispatchEvent(new CustomEvent('rbx1-select', { detail: o }));
}
async function loadScan() {
  try {
    const r = await fetch('/api/scan', { headers: headers(false) });
    const j = await r.json();
    if (j.error) return;
    state.lastScan = j.scans;
    state.detections = j.detections;
    showObjects();
    if (viewMode() === 'scan') showView();
  } catch (e) { /* the status badge says when rbx1d is away */ }
}
// A click on the scan picks the object whose centre is nearest (in image pixels).
$('view').addEventListener('click', (e) => {
  if (viewMode() !== 'scan' || !state.detections) return;
  const img = e.target;
  const x = (e.offsetX * img.naturalWidth) / img.clientWidth;
  const y = (e.offsetY * img.naturalHeight) / img.clientHeight;
  let best = null;
  for (const o of state.detections.objects) {
    const d = Math.hypot(o.centroid_px[0] - x, o.centroid_px[1] - y);
    if (!best || d < best.d) best = { d, o };
  }
  if (best) select(best.o.index);
});

// ---- the event log (server-sent events) ---------------------------------------------------------------------
function summary(e) {
  if (e.request) return 'request ' + JSON.stringify(e.request);
  if (e.result !== undefined) return 'result ' + JSON.stringify(e.result).slice(0, 300);
  if (e.error) return 'error ' + e.error.code + ': ' + e.error.message;
  if (e.scan !== undefined) return 'scan #' + e.scan + ': ' + e.objects + ' objects';
  const skip = new Set(['ts', 't_ms', 'event', 'req', 'cmd', 'seq', 'detections', 'report']);
  const rest = Object.entries(e).filter(([k]) => !skip.has(k)).map(([k, v]) => k + '=' + JSON.stringify(v));
  return e.event + ' ' + rest.join(' ').slice(0, 300);
}
function logLine(e, event, text) {
  const li = document.createElement('li');
  li.value = e.seq;
  li.dataset.event = event;
  li.dataset.cmd = e.cmd || '';
  li.className = event;
  li.textContent = (e.ts ? e.ts.slice(11, 23) + ' ' : '') + (e.cmd ? '[' + e.cmd + ' #' + e.req + '] ' : '') + text;
  li.title = JSON.stringify(e);  // the whole line on hover (the text is cut at 300 characters)
  const log = $('log');
  const atEnd = log.scrollTop + log.clientHeight >= log.scrollHeight - 4;
  log.appendChild(li);
  while (log.children.length > 500) log.firstChild.remove();
  if (atEnd) log.scrollTop = log.scrollHeight;
  return li;
}
function logEvent(e) {
  const event = e.event || (e.result !== undefined ? 'result' : e.error ? 'error' : e.request ? 'request' : 'scan');
  const li = logLine(e, event, summary(e));
  if (STEP_EVENTS.has(e.event)) li.classList.add('stepline');  // shown with "every step" (#log.verbose)
  if (e.req !== undefined) foldPhase(e);
}

// ---- a job's motion for people: sent/step/step_done folded into one line per phase, as the CLI's PhaseFold and
// tools/demo print them ("moved approach  49 segments  1.21 s"), and the job's progress (phase, steps, time) ------
const STEP_EVENTS = new Set(['sent', 'step', 'step_done']);
const folds = new Map();  // request number -> its fold: the phase being counted, the plan's step count
function foldPhase(e) {
  let f = folds.get(e.req);
  if (!f) folds.set(e.req, f = { name: null, count: 0, t0: 0, t1: 0, li: null, total: null, done: 0, t: 0 });
  if (e.t_ms !== undefined) f.t = e.t_ms / 1000;  // the final line has no time of its own: the last event's
  const t = f.t;
  if (e.event === 'planned') f.total = e.steps, f.done = 0;
  if (e.event === 'sent' && e.step === 1 && f.total && f.done === f.total) f.total = null;  // a move after the plan
  if (e.event === 'step_done') {
    if (e.name !== f.name) {  // a new phase starts where the last one ended
      f.name = e.name, f.count = 0, f.t0 = f.t1;
      f.li = logLine(e, 'phase', '');
    }
    f.count += 1;
    f.t1 = t;
    f.done = f.total && e.step <= f.total ? e.step : null;
    f.li.textContent = (e.ts ? e.ts.slice(11, 23) + ' ' : '') + '[' + e.cmd + ' #' + e.req + '] moved ' +
      f.name.padEnd(10) + ' ' + String(f.count).padStart(3) + (f.count === 1 ? ' segment  ' : ' segments ') +
      (f.t1 - f.t0).toFixed(2).padStart(6) + ' s';
  } else if (!STEP_EVENTS.has(e.event)) {
    f.name = null;  // any other line ends the phase
  } else if (f.name === null) {
    f.t1 = t;
  }
  showProgress(e, f, t);
  if (e.result !== undefined || e.error) folds.delete(e.req);
}
// One line for the running job: what it does now, the plan's steps done of its total, the time since its request.
function showProgress(e, f, t) {
  const p = $('motion-progress');
  let now = STEP_EVENTS.has(e.event) ? f.name || e.name : e.event === 'progress' ? e.phase : e.event;
  if (e.result !== undefined) now = 'done';
  else if (e.error) now = e.error.code;
  if (!now) return;  // the request line
  const steps = f.total ? (f.done === null ? '' : ', ' + f.done + ' of ' + f.total + ' steps') : '';
  p.textContent = e.cmd + ' #' + e.req + ': ' + now + steps + ', ' + t.toFixed(1) + ' s';
  p.dataset.cmd = e.cmd;
  p.dataset.done = f.total && f.done !== null ? f.done : '';
  p.dataset.total = f.total || '';
}
$('log-verbose').addEventListener('change', () => $('log').classList.toggle('verbose', $('log-verbose').checked));
function connectEvents() {
  if (state.events) state.events.close();
  state.events = new EventSource(withToken('/api/events?page=' + pageId));
  state.events.onmessage = (m) => {
    const e = JSON.parse(m.data);
    logEvent(e);
    document.dispatchEvent(new CustomEvent('rbx1-event', { detail: e }));  // the 3D view (arm3d.js)
    if (e.scan !== undefined) loadScan();
    if (e.result !== undefined || e.error || e.event === 'estop') pollStatus();
    if (e.cmd === 'sort' || e.cmd === 'clear') showJob(e);
  };
  state.events.addEventListener('status', (m) =>
    document.dispatchEvent(new CustomEvent('rbx1-status', { detail: JSON.parse(m.data) })));
}
$('log-clear').addEventListener('click', () => $('log').replaceChildren());

// ---- buttons ------------------------------------------------------------------------------------------------
action('scan', () => call('scan'));
action('home', () => call('home'));
action('clear-fault', () => call('clear_fault'));
action('pick', () => {
  const name = $('pick-name').value.trim();
  const place = $('pick-place').value.trim();
  if (!name || !place) return say('pick: choose an object (click it) and a place', 'error');
  return call('pick', { name, place });
});

$('token').value = state.token;
$('token').addEventListener('change', () => {
  state.token = $('token').value.trim();
  localStorage.setItem('rbx1.token', state.token);
  connectEvents();
  showView();
  loadScan();
  pollStatus();
  loadInfo();
});

// ---- operator commands (shown when the daemon knows them) -----------------------------------------------------
function jogJoint(sign) {
  return call('jog', { joint: Number($('jog-joint').value), deg: sign * Number($('jog-deg').value) });
}
action('jog-minus', () => jogJoint(-1));
action('jog-plus', () => jogJoint(1));
document.querySelectorAll('button.jog-mm').forEach((b) => b.addEventListener('click', async () => {
  const mm = [0, 0, 0];
  mm[Number(b.dataset.axis)] = Number(b.dataset.sign) * Number($('jog-mm').value);
  b.disabled = true;
  try { await call('jog', { mm }); } finally { b.disabled = false; }
}));
action('pose-save', () => call('pose_save', { name: 'scan' }));
action('place-save', () => call('place_save', { name: $('place-name').value.trim() }).then(pollStatus));
action('background', () => call('background'));
action('teach', async () => {
  if (!state.selected) return say('teach: click the object in the scan first', 'error');
  const reply = await call('teach', { index: state.selected, name: $('teach-name').value.trim() });
  // Taught, but a look-alike of an entry already there (issue 27): said, not the plain "done".
  const warnings = (reply.result && reply.result.warnings) || [];
  if (warnings.length) say('teach: warning: ' + warnings.join(' '), 'error');
  return reply;
});
// The calibration's replies as the operator reads them: markers seen, what is left to touch, the residuals.
function calibText(action, r) {
  if (r.error) return r.error.code + ': ' + r.error.message;
  const x = r.result;
  const mm = (p) => p.map((v) => num(v, 2)).join(', ') + ' mm';
  if (action === 'start')
    return x.markers.length + ' markers seen: ' + x.markers.map((m) => m.id).join(' ') + '\n' +
           'Jog the tool point onto a marker\'s centre, fingertips on the table, then Record it.';
  if (action === 'record')
    return 'marker ' + x.marker + ' recorded at ' + mm(x.mm) + ' (' + x.recorded + ' recorded)\n' +
           (x.remaining.length ? 'left to touch: ' + x.remaining.join(' ') : 'every marker recorded: Fit');
  if (action === 'cancel') return (x.cancelled ? 'cancelled' : 'nothing to cancel') + ': the ' + x.in_force + ' map stays in force';
  if (action === 'status') return x.active ? 'calibrating' : 'no calibration running; in force: ' + x.in_force;
  const head = x.model + ' over ' + x.markers.length + ' markers: RMS ' + num(x.rms_mm, 3) + ' mm, worst leave-one-out ' +
               num(x.max_loo_mm, 3) + ' mm, table at z ' + num(x.table_z_mm, 2) + ' mm';
  const verdict = x.saved ? 'saved to ' + x.saved + ': in force' : x.accepted ? 'accepted: Save to use it'
    : 'refused: ' + x.reason + ' (re-record the marker with the largest leave-one-out error, or Cancel)';
  const rows = x.markers.map((m) => String(m.id).padStart(6) + num(m.residual_mm, 3).padStart(10) + num(m.loo_mm, 3).padStart(15));
  return head + '\n' + verdict + '\nmarker  residual  leave-one-out (mm)\n' + rows.join('\n');
}
async function calib(body) {
  const r = await call('calibrate_workspace', body);
  $('calib-out').textContent = calibText(body.action, r);
  // The next marker to touch, ready in the field.
  const x = r.result || {};
  const next = body.action === 'start' && x.markers ? x.markers.map((m) => m.id) : x.remaining;
  if (next && next.length) $('calib-marker').value = next[0];
  return r;
}
action('calib-start', () => calib({ action: 'start' }));
action('calib-record', () => calib({ action: 'record', marker: Number($('calib-marker').value) }));
action('calib-fit', () => calib({ action: 'fit' }));
action('calib-save', () => calib({ action: 'save' }));
action('calib-cancel', () => calib({ action: 'cancel' }));

// ---- the cell's jobs: a sort or clear runs long; its POST is answered when it started (202), its progress comes
// with the event stream (any client's job: the CLI's too) ------------------------------------------------------
const job = { running: false, paused: false, elapsed: 0, at: 0, recipes: {} };
function jobButtons() {
  $('sort').disabled = $('clear').disabled = job.running;
  $('job-pause').disabled = !job.running || job.paused;
  $('job-resume').disabled = !job.paused;
  $('job-cancel').disabled = !job.running;
}
function jobButton(id, fn) {
  $(id).addEventListener('click', async () => {
    $(id).disabled = true;
    try { await fn(); } finally { jobButtons(); }
  });
}
function duration(s) {
  s = Math.max(0, Math.round(s));
  return s < 60 ? s + ' s' : Math.floor(s / 60) + ' min ' + String(s % 60).padStart(2, '0') + ' s';
}
function setProgress(fields) {
  for (const [k, v] of Object.entries(fields)) $('jp-' + k).textContent = v === undefined || v === null ? '–' : v;
}
// The elapsed time goes on between the job's progress events.
setInterval(() => { if (job.running) setProgress({ elapsed: duration(job.elapsed + (performance.now() - job.at) / 1000) }); }, 500);

// Objects left at a job's end: none to pick when it is done (else as the last progress said), and what it leaves
// on purpose: classes the recipe does not map, objects skipped.
function leftAtEnd(r) {
  const unmapped = Object.values(r.left).reduce((a, b) => a + b, 0);
  const notes = [unmapped && unmapped + ' not in the recipe', r.skipped.length && r.skipped.length + ' skipped'];
  const left = r.outcome === 'done' ? '0' : $('jp-left').textContent;
  return left + (notes.some(Boolean) ? ' (' + notes.filter(Boolean).join(', ') + ')' : '');
}
function showJob(e) {
  const p = $('job-progress');
  if (e.event === 'sort_started') {
    Object.assign(job, { running: true, paused: false, elapsed: 0, at: performance.now() });
    setProgress({ job: e.job + ' (' + e.kind + ')', phase: 'started', picked: 0, left: null, rate: null });
    $('job-summary').textContent = '';
    $('job-summary').title = '';
    p.dataset.phase = 'started';
  } else if (e.event === 'progress') {
    Object.assign(job, { running: true, paused: e.phase === 'paused', elapsed: e.elapsed_s, at: performance.now() });
    setProgress({ job: e.job + ' (' + e.cmd + ')', phase: e.phase, picked: e.picked + ' (' + e.attempts + ' attempts)',
                  left: e.left, elapsed: duration(e.elapsed_s), rate: e.rate_per_min + ' picks/min' });
    p.dataset.phase = e.phase;
  } else if (e.result !== undefined || e.error) {
    Object.assign(job, { running: false, paused: false });
    const r = e.result;
    $('job-summary').textContent = r
      ? `${e.cmd} (job ${r.job}) ${r.outcome}: picked ${r.picked_total} in ${r.elapsed_s} s (${r.picks_per_min}/min), ` +
        `failed ${r.failed}, skipped ${r.skipped.length}` + r.skipped.map((x) => ` [${x.class}: ${x.reason}]`).join('')
      : `${e.cmd}: ${e.error.code}: ${e.error.message}`;
    if (r) setProgress({ phase: r.outcome, picked: r.picked_total + ' (' + r.attempts + ' attempts)',
                         left: leftAtEnd(r), elapsed: duration(r.elapsed_s), rate: r.picks_per_min + ' picks/min' });
    else setProgress({ phase: e.error.code });
    p.dataset.phase = 'ended';
  } else if (e.event === 'skipped') {
    $('job-summary').title += `skipped ${e.class}: ${e.reason} ${e.detail || ''}\n`;
  }
  jobButtons();
}

// Recipes: the saved ones to choose from (recipes.json), or the editor's own (run as it is, or saved by a name).
async function loadRecipes(select) {
  try {
    const r = await fetch('/api/recipes', { headers: headers(false) });
    const j = await r.json();
    if (!j.result) return;
    job.recipes = j.result.recipes;
    const names = Object.keys(job.recipes).sort();
    const list = $('recipe-choice');
    const keep = select || list.value;
    list.replaceChildren(new Option('(as edited below)', ''), ...names.map((n) => new Option(n, n)));
    list.value = names.includes(keep) ? keep : names[0] || '';
    $('recipe-names').textContent = 'classes: ' + [...j.result.classes, '"*" (every other)', '"unknown"'].join(', ') +
                                    '; places: ' + j.result.places.join(', ');
    chooseRecipe();
  } catch (e) { /* the status badge says when rbx1d is away */ }
}
function chooseRecipe() {
  const name = $('recipe-choice').value;
  if (!name) return;
  $('recipe-text').value = JSON.stringify(job.recipes[name], null, 1).replace(/\n\s*/g, ' ');
  $('recipe-name').value = name;
}
$('recipe-choice').addEventListener('change', chooseRecipe);
$('recipe-text').addEventListener('input', () => { $('recipe-choice').value = ''; });  // edited: run what is typed
function editedRecipe() {
  try {
    const r = JSON.parse($('recipe-text').value);
    return r && typeof r === 'object' && !Array.isArray(r) ? r : null;
  } catch (e) { return null; }
}
function recipeMessage(text, kind) {
  $('recipe-msg').textContent = text;
  $('recipe-msg').className = kind;
}
async function startJob(cmd, body) {
  const r = await call(cmd, body);
  if (r.started) Object.assign(job, { running: true, paused: false });
  return r;
}
jobButton('sort', () => {
  const recipe = $('recipe-choice').value || editedRecipe();
  if (!recipe) {
    $('recipe-editor').open = true;
    return recipeMessage('choose a saved recipe, or type one: {"CLASS": "PLACE", ...}', 'error');
  }
  return startJob('sort', { recipe });
});
jobButton('clear', () => startJob('clear', { place: $('clear-place').value.trim() }));
jobButton('job-pause', () => call('pause'));
jobButton('job-resume', () => call('resume'));
jobButton('job-cancel', () => call('cancel'));
action('recipe-save', async () => {
  const name = $('recipe-name').value.trim();
  const recipe = editedRecipe();
  if (!name || !recipe) return recipeMessage('a name and a JSON object {"CLASS": "PLACE", ...}', 'error');
  const r = await call('recipe_save', { name, recipe });
  if (r.error) return recipeMessage(r.error.code + ': ' + r.error.message, 'error');
  recipeMessage('saved "' + name + '" in ' + r.result.file, 'ok');
  return loadRecipes(name);
});

async function loadInfo() {
  try {
    const r = await fetch('/api/info', { headers: headers(false) });
    const j = await r.json();
    if (j.places) showPlaces(j.places);
    const has = new Set(j.commands || []);
    $('jog-panel').hidden = !has.has('jog');
    $('teach-panel').hidden = !(has.has('pose_save') || has.has('place_save') || has.has('background') || has.has('teach'));
    $('calib-panel').hidden = !has.has('calibrate_workspace');
    $('jobs-panel').hidden = !has.has('sort');
    if (has.has('recipes')) loadRecipes();
  } catch (e) { /* optional */ }
}

connectEvents();
loadInfo();
loadScan();
pollStatus();
setInterval(pollStatus, 1000);
