// history.js - the history page: /api/history as two tables and two charts (Chart.js from Debian, served by rbx1d).
'use strict';

const $ = (id) => document.getElementById(id);
let token = localStorage.getItem('rbx1.token') || '';
const charts = {};

function say(text, kind) {
  $('message').textContent = text;
  $('message').className = kind || '';
}
function cell(tr, v) {
  const td = document.createElement('td');
  td.textContent = v === null || v === undefined ? '–' : v;
  tr.appendChild(td);
  return td;
}
function fill(id, rows, columns) {
  const body = document.querySelector('#' + id + ' tbody');
  body.replaceChildren(...rows.map((r) => {
    const tr = document.createElement('tr');
    columns.forEach((c) => cell(tr, c(r)));
    return tr;
  }));
}

function withToken(url) { return token ? url + '?token=' + encodeURIComponent(token) : url; }
function showScan(p) {
  const fig = $('scan-figure');
  if (!p.scan || !p.image) {
    fig.hidden = true;
    return say('pick ' + p.id + ': no scan image kept (the [history] max_mb budget removes the oldest)', 'error');
  }
  $('scan-image').src = withToken('/api/history/scan/' + p.scan + '.jpg');
  $('scan-caption').textContent = `pick ${p.id} (job ${p.job}): ${p.class} -> ${p.place || '–'}, ${p.outcome}` +
                                  (p.reason ? ' (' + p.reason + ')' : '') + `, scan ${p.scan}`;
  fig.hidden = false;
}

function showTables(h) {
  fill('jobs', h.jobs, [(j) => j.id, (j) => j.kind, (j) => JSON.stringify(j.recipe), (j) => j.started,
    (j) => j.ended, (j) => j.outcome, (j) => j.summary && j.summary.picked_total, (j) => j.summary && j.summary.picks_per_min]);
  fill('picks', h.picks, [(p) => p.id, (p) => p.job, (p) => p.ts.slice(11, 19), (p) => p.class,
    (p) => p.match_score === null ? null : p.match_score.toFixed(2), (p) => p.place, (p) => p.outcome,
    (p) => p.reason, (p) => (p.cycle_ms / 1000).toFixed(1), (p) => p.attempt]);
  document.querySelectorAll('#picks tbody tr').forEach((tr, i) => tr.addEventListener('click', () => showScan(h.picks[i])));
}

function chart(id, config) {
  if (charts[id]) charts[id].destroy();
  config.options = Object.assign({ responsive: true, maintainAspectRatio: false, animation: false }, config.options);
  charts[id] = new Chart($(id), config);
}

const OUTCOME_COLOURS = { picked: '#15803d', failed: '#b91c1c', skipped: '#b45309', unchecked: '#6b7280' };

function showCharts(h) {
  const classes = [...new Set(h.picks.map((p) => p.class))].sort();
  const outcomes = [...new Set(h.picks.map((p) => p.outcome))].sort();
  chart('chart-classes', {
    type: 'bar',
    data: { labels: classes, datasets: outcomes.map((o) => ({
      label: o, backgroundColor: OUTCOME_COLOURS[o] || '#1d4ed8',
      data: classes.map((c) => h.picks.filter((p) => p.class === c && p.outcome === o).length) })) },
    options: { scales: { x: { stacked: true }, y: { stacked: true, beginAtZero: true, ticks: { precision: 0 } } } },
  });
  // The latest job with attempts: cycle time per pick, in the order they were made.
  const attempts = h.picks.filter((p) => p.outcome !== 'skipped');
  const job = attempts.length ? attempts[0].job : null;
  const picks = attempts.filter((p) => p.job === job).reverse();
  $('cycle-job').textContent = job ? '(job ' + job + ')' : '(no picks yet)';
  chart('chart-cycle', {
    type: 'line',
    data: { labels: picks.map((p, i) => i + 1 + ' ' + p.class), datasets: [{
      label: 'cycle (s)', borderColor: '#1d4ed8', backgroundColor: '#1d4ed8',
      data: picks.map((p) => p.cycle_ms / 1000) }] },
    options: { scales: { y: { beginAtZero: true, title: { display: true, text: 's' } } } },
  });
}

async function load() {
  try {
    const r = await fetch('/api/history?limit=500', { headers: token ? { Authorization: 'Bearer ' + token } : {} });
    const j = await r.json();
    if (j.error) return say('history: ' + j.error.code + ': ' + j.error.message, 'error');
    showTables(j.result);
    if (typeof Chart === 'undefined') return say('charts: /chart.js did not load (apt install libjs-chart.js)', 'error');
    showCharts(j.result);
    say(j.result.jobs.length + ' jobs, ' + j.result.picks.length + ' picks', 'ok');
  } catch (e) {
    say('rbx1d did not answer: ' + e, 'error');
  }
}

$('token').value = token;
$('token').addEventListener('change', () => {
  token = $('token').value.trim();
  localStorage.setItem('rbx1.token', token);
  load();
});
load();
setInterval(load, 10000);
