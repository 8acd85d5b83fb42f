// goalvla operator console: renders what the runtime publishes and posts the operator's actions.
"use strict";
const $ = (id) => document.getElementById(id);
let plan = null;
let state = "";

async function post(action, body = {}) {
  const r = await fetch("/api/" + action, {
    method: "POST", headers: { "Content-Type": "application/json", "X-Goalvla": "1" }, body: JSON.stringify(body),
  });
  if (!r.ok) addEvent({ level: "error", text: action + " refused: " + (await r.text()) });
}

function addEvent(e) {
  const li = document.createElement("li");
  li.className = e.level || "info";
  li.textContent = new Date().toLocaleTimeString() + "  " + e.text;
  $("events").prepend(li);
  while ($("events").children.length > 200) $("events").lastElementChild.remove(); // a flood stays a page
}

function refreshConfirm() {
  const ready = state === "AWAITING_CONFIRM" && plan !== null;
  $("confirm-btn").disabled = !ready;
  $("confirm-btn").textContent = ready ? "Confirm plan " + plan.plan_id : "Confirm";
  $("confirm-what").textContent = ready
    ? `executes plan ${plan.plan_id}: ${plan.mode || "motion"}, ${plan.duration_s.toFixed(1)} s, "${plan.instruction}"`
    : "";
}

function showPlan(p) {
  plan = p;
  const fmt = (x, d = 2) => (x === null || x === undefined ? "n/a" : Number(x).toFixed(d));
  $("plan-id").textContent = p.plan_id;
  $("plan-mode").textContent = p.mode || "—";
  $("plan-duration").textContent = fmt(p.duration_s, 1) + " s, " + p.samples + " samples";
  $("plan-speeds").textContent = p.peak_joint_speed_rad_s.map((v) => fmt(v)).join(" ") + " rad/s";
  $("plan-clearance").textContent =
    p.min_clearance_m === null ? "n/a" : "≥ " + fmt(p.min_clearance_m * 1000, 0) + " mm (gate padding)";
  $("plan-motion").textContent = JSON.stringify(p.object_motion);
  $("plan-gate").textContent = p.gate_ok ? "passed" : "FAILED";
  refreshConfirm();
}

function showStatus(s) {
  if (plan && s.run_id && plan.run_id !== s.run_id) plan = null; // a plan of an earlier run is never confirmable
  state = s.state;
  $("state").textContent = s.state;
  $("state").className = "state " + s.state;
  $("reason").textContent = s.reason;
  $("run-id").textContent = s.run_id || "—";
  $("run-instruction").textContent = s.instruction || "—";
  refreshConfirm();
}

function showJoints(j) {
  const deg = j.q_rad.map((q) => ((q * 180) / Math.PI).toFixed(1));
  const grip = j.gripper_width_m === null ? "" : `  gripper ${(j.gripper_width_m * 1000).toFixed(0)} mm`;
  $("joints").textContent = deg.join("°  ") + "°" + grip + (j.fault_code ? "  FAULT " + j.fault_code : "");
}

function connect() {
  const es = new EventSource("/events");
  es.onopen = () => { $("conn").textContent = "connected"; $("conn").className = "ok"; };
  es.onerror = () => { $("conn").textContent = "disconnected"; $("conn").className = "bad"; };
  es.onmessage = (m) => {
    const { type, data } = JSON.parse(m.data);
    if (type === "status") showStatus(data);
    else if (type === "plan") showPlan(data);
    else if (type === "event") addEvent(data);
    else if (type === "joint_state") showJoints(data);
    else if (type === "image") {
      const img = $("img-" + data.name);
      if (img) img.src = `/image/${data.name}?v=${data.version}`;
    }
  };
}

window.addEventListener("DOMContentLoaded", () => {
  $("estop-btn").onclick = () => post("estop");
  document.addEventListener("keydown", (e) => { if (e.key === "Escape") post("estop"); });
  $("run-form").onsubmit = (e) => { e.preventDefault(); post("run", { instruction: $("instruction").value }); };
  $("confirm-btn").onclick = () => { if (plan) post("confirm", { plan_id: plan.plan_id }); };
  $("abort-btn").onclick = () => post("abort");
  $("reset-btn").onclick = () => post("reset");
  connect();
});
