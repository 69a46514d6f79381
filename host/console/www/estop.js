// estop.js - the E-STOP of every console page (index.html, history.html): POST /api/estop at once, on its own,
// never behind the page's other requests (a sort's or a pick's); also the Esc key, and Space outside a text field.
'use strict';

async function estop() {
  const m = document.getElementById('message');
  const say = (text) => { m.textContent = text; m.className = 'error'; };
  say('E-STOP sent…');
  const token = localStorage.getItem('rbx1.token') || '';
  const h = { 'Content-Type': 'application/json' };
  if (token) h.Authorization = 'Bearer ' + token;
  try {
    const r = await (await fetch('/api/estop', { method: 'POST', headers: h, body: '{}' })).json();
    say(r.result ? 'E-STOP latched' + (r.result.aborted_job ? ' (job aborted)' : '') + ': clear the fault to go on'
                 : 'estop: ' + r.error.code + ': ' + r.error.message);
  } catch (e) {
    say('E-STOP: rbx1d did not answer: ' + e);
  }
}
document.getElementById('estop').addEventListener('click', estop);
document.addEventListener('keydown', (e) => {
  const typing = ['INPUT', 'TEXTAREA', 'SELECT'].includes(e.target.tagName);
  if (e.key === 'Escape' || (e.key === ' ' && !typing)) { e.preventDefault(); estop(); }
});
