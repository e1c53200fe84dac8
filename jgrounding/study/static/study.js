"use strict";
// Shared by the operator's and the participant's pages: the token, the JSON API, the trunk drawing.
const token = new URLSearchParams(location.search).get("token");
const $ = (id) => document.getElementById(id);

async function api(path, body) {
  const headers = {"Content-Type": "application/json"};
  if (token) headers["Authorization"] = "Bearer " + token;
  const r = await fetch("/study/api/" + path, body === undefined ? {headers} : {method: "POST", headers, body: JSON.stringify(body)});
  const msg = await r.json();
  if (!r.ok || msg.ok === false) throw new Error(msg.error || r.statusText);
  return msg;
}

function withToken(url) { return token ? url + (url.includes("?") ? "&" : "?") + "token=" + encodeURIComponent(token) : url; }

// The simulated trunk, as the policy server's page draws it: side view and view from behind.
function drawTrunk(canvas, scene, points) {
  const g = canvas.getContext("2d");
  g.clearRect(0, 0, canvas.width, canvas.height);
  for (const v of [{ox: 0, h: 0, label: "side view"}, {ox: 270, h: 1, label: "from behind"}]) {
    const px = (p) => v.ox + 110 + 230 * (v.h ? p[1] : p[0]), pz = (z) => 320 - 240 * (z - 0.2);
    g.fillStyle = "#333"; g.font = "12px sans-serif"; g.fillText(v.label, v.ox + 10, 16);
    if (scene && !v.h) {
      const ut = scene.user_torso, hd = scene.user_head;
      g.fillStyle = "#cdd6e0";
      g.fillRect(px([ut.x - ut.radius, 0]), pz(ut.z[1]), 230 * 2 * ut.radius, pz(ut.z[0]) - pz(ut.z[1]));
      g.beginPath(); g.arc(px([hd[0], 0]), pz(hd[2]), 230 * hd[3], 0, 2 * Math.PI); g.fill();
    }
    g.fillStyle = "#8d99ae"; g.beginPath(); g.arc(px([-0.05, 0]), pz(1.18), 26, 0, 2 * Math.PI); g.fill();
    if (!points) continue;
    g.strokeStyle = "#6c584c"; g.lineCap = "round";
    for (let i = 0; i + 1 < points.length; i++) {
      g.lineWidth = 16 - 11 * i / (points.length - 1);
      g.beginPath(); g.moveTo(px(points[i]), pz(points[i][2])); g.lineTo(px(points[i + 1]), pz(points[i + 1][2])); g.stroke();
    }
  }
}
