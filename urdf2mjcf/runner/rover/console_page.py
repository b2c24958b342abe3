"""The console's page (``GET /``): plain HTML and JavaScript that does everything through
the HTTP/JSON API of ``console.py`` with ``fetch()``; no file of its own to install.

Names come from the bundle (rovers, joints, cameras), which travels between people:
the page puts them in as text (``textContent``, ``new Option``, ``encodeURIComponent``
in a path), never as HTML. Its ``Content-Security-Policy`` (:data:`CSP`) runs only its
own script and style (by their hashes) and loads only from the console, so markup
that got in anyway would run nothing and send nothing elsewhere.
"""

import base64
import hashlib
import re

PAGE = """<!doctype html>
<html lang="en">
<head>
<meta charset="utf-8">
<title>rover console</title>
<style>
  body { font: 14px sans-serif; margin: 12px; background: #f4f4f4; }
  header { display: flex; gap: 12px; align-items: center; margin-bottom: 10px; }
  #estop { background: #c00; color: #fff; font-weight: bold; padding: 10px 24px;
           border: 3px solid #600; border-radius: 6px; }
  #banner { color: #c00; font-weight: bold; }
  main { display: flex; gap: 16px; align-items: flex-start; }
  #cameras { display: grid; grid-template-columns: repeat(2, 322px); gap: 6px; }
  figure { margin: 0; } figure img { width: 320px; border: 1px solid #999; background: #000; }
  figcaption { font-size: 12px; }
  table { border-collapse: collapse; } td, th { padding: 2px 8px; text-align: right; }
  label { display: flex; gap: 8px; align-items: center; } label span { width: 190px; }
  input[type=range] { width: 220px; } .bad { color: #c00; }
</style>
</head>
<body>
<header>
  <label>rover <select id="rover"></select></label>
  <span>t = <b id="time">-</b> s</span>
  <button id="estop">EMERGENCY STOP</button> <button id="release">Release</button>
  <span id="banner"></span> <span id="status"></span>
</header>
<main>
  <section id="cameras"></section>
  <section>
    <table>
      <tr><th></th><th>x m</th><th>y m</th><th>z m</th><th>yaw deg</th></tr>
      <tr id="pose"><th>true pose</th><td></td><td></td><td></td><td></td></tr>
      <tr id="odometry"><th>wheel odometry</th><td></td><td></td><td></td><td></td></tr>
      <tr id="odometry_imu"><th>wheels + IMU</th><td></td><td></td><td></td><td></td></tr>
    </table>
    <h4>IMU</h4>
    <table>
      <tr><th>roll, pitch, yaw deg</th><td id="rpy"></td></tr>
      <tr><th>angular velocity rad/s</th><td id="gyro"></td></tr>
      <tr><th>linear acceleration m/s&sup2;</th><td id="accel"></td></tr>
      <tr><th>wheels left, right rad/s</th><td id="wheels"></td></tr>
    </table>
    <h4>Wheels (rad/s)</h4>
    <label><span>left</span><input id="left" type="range" step="0.1"><output></output></label>
    <label><span>right</span><input id="right" type="range" step="0.1"><output></output></label>
    <button id="stop">wheels 0</button>
    <h4>Arm joint targets (rad)</h4>
    <div id="arm"></div>
  </section>
</main>
<script>
"use strict";
const $ = (id) => document.getElementById(id);
let info = {}, rover = null;

async function api(method, path, body) {
  const init = { method };
  if (body !== undefined) {
    init.headers = { "Content-Type": "application/json" };
    init.body = JSON.stringify(body);
  }
  const r = await fetch(path, init);
  const data = await r.json();
  if (!r.ok) throw new Error(data.error);
  return data;
}
function say(text, bad) {
  $("status").textContent = text;
  $("status").className = bad ? "bad" : "";
}
const fmt = (xs, k = 3) => xs.map((x) => x.toFixed(k)).join(", ");
const deg = (r) => r * 180 / Math.PI;

function rpy([w, x, y, z]) {
  return [Math.atan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y)),
          Math.asin(Math.max(-1, Math.min(1, 2 * (w * y - z * x)))),
          Math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))].map(deg);
}
function pose(row, p) {
  [...p.xyz.map((x) => x.toFixed(3)), deg(p.yaw).toFixed(2)]
    .forEach((text, k) => { $(row).cells[k + 1].textContent = text; });
}

let sent = Promise.resolve();
function command(body) {  // one at a time: two in flight could land out of order
  const to = rover;
  sent = sent.then(() => api("POST", "/command", Object.assign({ rover: to }, body)))
    .then((r) => say(r.clipped.length ? "clipped: " + r.clipped.join(", ") : "ok"))
    .catch((e) => say(e.message, true));
}
function sendWheels() { command({ wheels: { left: +$("left").value, right: +$("right").value } }); }

function camera(name, cam) {
  const fig = document.createElement("figure"), img = new Image();
  const cap = document.createElement("figcaption");
  img.dataset.camera = cam; img.alt = cam; cap.textContent = cam;
  const src = `/camera/${encodeURIComponent(name)}/${encodeURIComponent(cam)}.png`;
  const load = () => {  // the next image once this one is shown, while the rover is
    if (rover === name && img.isConnected) img.src = `${src}?t=${Date.now()}`;
  };
  img.onload = () => {
    img.dataset.frames = +(img.dataset.frames || 0) + 1;  // images shown
    setTimeout(load, 200);
  };
  img.onerror = () => setTimeout(load, 1000);
  fig.append(img, cap);
  $("cameras").append(fig);
  load();
}

function slider(input, lo, hi, value, send) {
  Object.assign(input, { min: lo, max: hi, value });
  const out = input.nextElementSibling;
  out.textContent = (+input.value).toFixed(2);
  input.oninput = () => { out.textContent = (+input.value).toFixed(2); send(); };
}

async function show(name) {
  rover = name;
  const now = (await api("GET", "/state")).rovers[name], about = info[name];
  $("cameras").replaceChildren();
  about.cameras.forEach((cam) => camera(name, cam));
  const [lo, hi] = about.wheels;
  slider($("left"), lo, hi, now.targets.wheels.left, sendWheels);
  slider($("right"), lo, hi, now.targets.wheels.right, sendWheels);
  $("arm").replaceChildren();
  for (const [joint, [jlo, jhi]] of Object.entries(about.arm)) {
    const label = document.createElement("label"), span = document.createElement("span");
    const input = document.createElement("input");
    span.textContent = joint;  // a name from the bundle: text, never HTML
    Object.assign(input, { type: "range", step: "0.01", className: "joint" });
    input.dataset.joint = joint;
    label.append(span, input, document.createElement("output"));
    $("arm").append(label);
    slider(input, Math.max(jlo, -6.3), Math.min(jhi, 6.3), now.targets.arm[joint],
           () => command({ arm: { [joint]: +input.value } }));
  }
}

function follow(input, value) {  // a slider not in the user's hand shows the command
  if (document.activeElement !== input) {
    input.value = value;
    input.nextElementSibling.textContent = (+value).toFixed(2);
  }
}

async function poll() {
  let s;
  try { s = await api("GET", "/state"); } catch (e) { say(e.message, true); return; }
  const r = s.rovers[rover];
  $("time").textContent = s.time.toFixed(2);
  for (const row of ["pose", "odometry", "odometry_imu"]) pose(row, r[row]);
  $("rpy").textContent = fmt(rpy(r.imu.orientation), 2);
  $("gyro").textContent = fmt(r.imu.angular_velocity);
  $("accel").textContent = fmt(r.imu.linear_acceleration);
  $("wheels").textContent = fmt([r.wheels.left, r.wheels.right], 2);
  $("banner").textContent = r.estop ? "EMERGENCY STOP latched" : "";
  follow($("left"), r.targets.wheels.left);
  follow($("right"), r.targets.wheels.right);
  const joints = document.querySelectorAll("input.joint");
  for (const i of joints) follow(i, r.targets.arm[i.dataset.joint]);
}

const every = (path, done) => () => api("POST", path).then(() => say(done))
  .catch((e) => say(e.message, true));
$("estop").onclick = every("/estop", "stopped");  // every rover
$("release").onclick = every("/release", "released");
$("stop").onclick = () => { $("left").value = 0; $("right").value = 0; sendWheels(); };
$("rover").onchange = () => show($("rover").value);

(async () => {
  info = await api("GET", "/rovers");
  for (const name of Object.keys(info)) $("rover").add(new Option(name, name));
  await show($("rover").value);
  setInterval(poll, 200);
})();
</script>
</body>
</html>
"""


def _hash(tag: str) -> str:
    (body,) = re.findall(rf"<{tag}>(.*?)</{tag}>", PAGE, re.S)
    return "'sha256-" + base64.b64encode(hashlib.sha256(body.encode()).digest()).decode() + "'"


CSP = (
    f"default-src 'none'; script-src {_hash('script')}; style-src {_hash('style')}; "
    "img-src 'self'; connect-src 'self'; base-uri 'none'; form-action 'none'; "
    "frame-ancestors 'none'"
)
"""The page's Content-Security-Policy: its own script and style, the console's images
and API, nothing else."""
