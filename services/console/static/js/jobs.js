// The jobs view: submit a training job, follow its progress and log live, cancel it.
// Progress comes from the log: `coexist train` writes `<batch>: <done>/<total> steps` lines.

import {request} from "./api.js";
import {$, fill, h, when} from "./dom.js";
import {envs, notify} from "./shared.js";

const LIST_MS = 2000;
const LOG_MS = 1000;
const FINISHED = new Set(["succeeded", "failed", "cancelled"]);
const PROGRESS = /^(.+): (\d+)\/(\d+) steps$/gm;
let listTimer = null;
let follow = null; // {id, offset, timer, text}
let ready = false;

export async function show(params) {
  if (!ready) await setUp();
  await loadJobs();
  listTimer ??= setInterval(() => loadJobs().catch(() => {}), LIST_MS);
  const id = params.get("job");
  if (id && (!follow || follow.id !== id)) await followJob(id);
  if (!id) stopFollowing();
}

export function hide() {
  clearInterval(listTimer);
  listTimer = null;
  stopFollowing();
}

async function setUp() {
  const select = $("#job-env");
  for (const env of await envs()) select.append(h("option", {value: env.name}, env.name));
  $("#job-form").addEventListener("submit", submit);
  ready = true;
}

async function submit(event) {
  event.preventDefault();
  const steps = $("#job-steps").value.trim();
  const body = {
    kind: $("#job-kind").value, env: $("#job-env").value,
    goals: $("#job-goals").value.trim() || "all", combos: $("#job-combos").value.trim(),
    seed: Number($("#job-seed").value || 0),
  };
  if (steps) body.steps = Number(steps);
  try {
    const job = await request("/v1/jobs", {method: "POST", body});
    notify(`job ${job.id} queued`, "ok");
    location.hash = `#/jobs?job=${job.id}`;
  } catch (err) {
    notify(err.explain ? err.explain() : String(err));
  }
}

async function loadJobs() {
  const body = await request("/v1/jobs?limit=50");
  fill($("#jobs-table tbody"), body.jobs.map((job) => h("tr", {dataset: {job: job.id}},
    h("th", {scope: "row"}, h("a", {href: `#/jobs?job=${job.id}`}, job.id.slice(0, 8))),
    h("td", {}, job.kind), h("td", {}, job.args.env), h("td", {}, job.args.goals || job.args.combos),
    h("td", {class: `status ${job.status}`}, job.status), h("td", {}, when(job.created_at)))));
}

function stopFollowing() {
  if (follow) clearTimeout(follow.timer);
  follow = null;
}

async function followJob(id) {
  stopFollowing();
  follow = {id, offset: 0, timer: null, text: ""};
  const detail = $("#job-detail");
  fill(detail,
    h("h3", {id: "job-title"}, `Job ${id}`),
    h("dl", {class: "facts", id: "job-facts"}),
    h("div", {class: "progress-line"},
      h("label", {for: "job-progress", id: "job-progress-label"}, "Progress"),
      h("progress", {id: "job-progress", max: 1, value: 0}),
      h("span", {id: "job-progress-text", class: "muted"}, "no progress line yet")),
    h("div", {class: "actions", id: "job-actions"}),
    h("h4", {}, "Log"),
    h("pre", {id: "job-log", class: "log", tabindex: 0, role: "log", "aria-label": `log of job ${id}`}));
  detail.focus();
  await tick();
}

async function tick() {
  const current = follow;
  if (!current) return;
  try {
    const job = await request(`/v1/jobs/${current.id}`);
    const chunk = await request(`/v1/jobs/${current.id}/logs?offset=${current.offset}`);
    if (follow !== current) return;
    current.offset = chunk.next_offset;
    if (chunk.log) {
      current.text += chunk.log;
      const log = $("#job-log");
      const atEnd = log.scrollTop + log.clientHeight >= log.scrollHeight - 4;
      log.append(chunk.log);
      if (atEnd) log.scrollTop = log.scrollHeight;
    }
    renderJob(job, current.text);
    if (FINISHED.has(job.status) && !chunk.log) return; // the whole log is in
  } catch (err) {
    notify(err.explain ? err.explain() : String(err));
  }
  if (follow === current) current.timer = setTimeout(tick, LOG_MS);
}

function renderJob(job, text) {
  const fact = (term, value) => [h("dt", {}, term), h("dd", {}, value)];
  fill($("#job-facts"),
    fact("status", h("span", {class: `status ${job.status}`, id: "job-status"}, job.status)),
    fact("kind", job.kind), fact("env", job.args.env), fact("goals", job.args.goals),
    fact("seed", job.args.seed), fact("steps", job.args.steps ?? "the config's"),
    fact("created", when(job.created_at)), fact("started", when(job.started_at)),
    fact("finished", when(job.finished_at)), fact("exit code", job.exit_code ?? "–"));
  const last = [...text.matchAll(PROGRESS)].pop();
  if (last) {
    const [, batch, done, total] = last;
    $("#job-progress").value = Number(done) / Number(total);
    fill($("#job-progress-text"), `${batch}: ${done} of ${total} steps`);
  } else if (job.status === "succeeded") {
    $("#job-progress").value = 1;
  }
  const actions = $("#job-actions");
  if (["queued", "running"].includes(job.status)) {
    if (!actions.querySelector("button")) {
      fill(actions, h("button", {type: "button", class: "danger", onclick: () => cancel(job.id)},
        "Cancel job"));
    }
  } else {
    fill(actions);
  }
}

async function cancel(id) {
  try {
    const job = await request(`/v1/jobs/${id}`, {method: "DELETE"});
    notify(`job ${id}: ${job.status}`, "ok");
  } catch (err) {
    notify(err.explain ? err.explain() : String(err));
  }
}
