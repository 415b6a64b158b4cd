// The registry view: models with versions and aliases, a model's versions with promote /
// archive / delete, a version's lineage and training curve, and the change feed, polled live.

import {modelPath, request} from "./api.js";
import {dataTable, lineChart} from "./charts.js";
import {$, fill, h, num, when} from "./dom.js";
import {envs, notify} from "./shared.js";

const POLL_MS = 1500;
const FEED_LENGTH = 50;
let models = [];
let lastEventId = 0;
let poller = null;
let open = {model: null, version: null};

export async function show(params) {
  await fillEnvFilter();
  open = {model: params.get("model"), version: Number(params.get("version")) || null};
  await loadModels(true);
  startPolling();
  if (open.model) await showModel(open.model, open.version);
  else fill($("#model-detail"));
}

export function hide() {
  clearInterval(poller);
  poller = null;
}

async function fillEnvFilter() {
  const select = $("#filter-env");
  if (select.options.length > 1) return;
  for (const env of await envs()) select.append(h("option", {value: env.name}, env.name));
  for (const id of ["#filter-env", "#filter-kind", "#filter-text"]) {
    $(id).addEventListener("input", renderModels);
  }
}

async function loadModels(resetFeed = false) {
  const body = await request("/v1/console/models");
  models = body.models;
  if (resetFeed) {
    lastEventId = body.last_event_id;
    fill($("#feed"), [...body.recent_events].reverse().map(feedItem));
  }
  renderModels();
}

function aliasText(aliases) {
  return Object.entries(aliases).sort().map(([a, v]) => `${a}: v${v}`).join(", ") || "–";
}

function renderModels() {
  const env = $("#filter-env").value;
  const kind = $("#filter-kind").value;
  const text = $("#filter-text").value.trim().toLowerCase();
  const shown = models.filter((m) => (!env || m.env === env) && (!kind || m.kind === kind)
    && (!text || m.name.toLowerCase().includes(text) || m.goals.some((g) => g.toLowerCase() === text)));
  fill($("#models-caption"), `Models: ${shown.length} of ${models.length}`);
  fill($("#models-table tbody"), shown.map((m) => h("tr", {dataset: {model: m.name}},
    h("th", {scope: "row"}, h("a", {href: `#/registry?model=${encodeURIComponent(m.name)}`}, m.name)),
    h("td", {}, m.env), h("td", {}, m.kind), h("td", {}, m.goals.join(" + ")),
    h("td", {class: "versions"}, m.versions.map((v) => `v${v.version}${v.status === "archived" ? " (archived)" : ""}`).join(", ")),
    h("td", {class: "aliases"}, aliasText(m.aliases)),
    h("td", {}, m.tags.gate || "–"))));
}

// --- the change feed -------------------------------------------------------------------------

const EVENT_TEXT = {
  model_created: (e) => `model ${e.name} created`,
  model_updated: (e) => `model ${e.name} updated`,
  model_deleted: (e) => `model ${e.name} deleted`,
  version_registered: (e) => `${e.name} v${e.version} registered`,
  version_archived: (e) => `${e.name} v${e.version} archived`,
  version_deleted: (e) => `${e.name} v${e.version} deleted`,
  alias_set: (e) => `${e.name}: ${e.alias} → v${e.version}`,
  alias_deleted: (e) => `${e.name}: alias ${e.alias} removed`,
};

function feedItem(event) {
  const text = (EVENT_TEXT[event.kind] || ((e) => `${e.kind} ${e.name}`))(event);
  return h("li", {dataset: {event: event.id, kind: event.kind}},
    h("time", {datetime: event.at}, when(event.at)), " ", text);
}

function startPolling() {
  if (!poller) poller = setInterval(poll, POLL_MS);
}

async function poll() {
  let body;
  try {
    body = await request(`/v1/registry/events?since=${lastEventId}&limit=100`);
  } catch (err) {
    fill($("#feed-state"), `feed paused: ${err.explain ? err.explain() : err}`);
    return;
  }
  fill($("#feed-state"), "live: new versions and moved aliases appear here");
  if (!body.events.length) return;
  lastEventId = body.last_id;
  const feed = $("#feed");
  for (const event of body.events) feed.prepend(feedItem(event));
  while (feed.children.length > FEED_LENGTH) feed.lastElementChild.remove();
  await loadModels();
  if (open.model && body.events.some((e) => e.name === open.model)) {
    await showModel(open.model, open.version, {quiet: true});
  }
}

// --- one model ---------------------------------------------------------------------------

async function showModel(name, version, {quiet = false} = {}) {
  const detail = $("#model-detail");
  let model;
  try {
    model = await request(`/v1/registry/models/${modelPath(name)}`);
  } catch (err) {
    fill(detail, h("p", {class: "muted"}, err.explain ? err.explain() : String(err)));
    return;
  }
  const byVersion = {};
  for (const [alias, v] of Object.entries(model.aliases)) (byVersion[v] ??= []).push(alias);
  fill(detail,
    h("h3", {id: "model-title"}, model.name),
    h("p", {}, model.description || ""),
    h("dl", {class: "facts"},
      fact("env", model.env), fact("kind", model.kind), fact("goals", model.goals.join(" + ")),
      fact("observation / actions", `${model.obs_dim} / ${model.n_actions}`),
      fact("aliases", aliasText(model.aliases)),
      fact("tags", Object.entries(model.tags).map(([k, v]) => `${k}=${v}`).join(", ") || "–")),
    h("div", {class: "table-wrap"}, h("table", {class: "versions-table"},
      h("caption", {}, `Versions of ${model.name}`),
      h("thead", {}, h("tr", {}, ["Version", "Status", "Aliases", "Created", "sha256", "Actions"]
        .map((c) => h("th", {scope: "col"}, c)))),
      h("tbody", {}, model.versions.map((v) => versionRow(model, v, byVersion[v.version] || [])))),
    ),
    h("div", {id: "version-detail"}));
  const chosen = model.versions.find((v) => v.version === version);
  if (chosen) fill($("#version-detail", detail), lineage(model, chosen));
  if (!quiet) detail.focus();
}

function fact(term, value) {
  return [h("dt", {}, term), h("dd", {}, value)];
}

function versionRow(model, v, aliases) {
  const link = `#/registry?model=${encodeURIComponent(model.name)}&version=${v.version}`;
  const actions = h("td", {class: "actions"});
  const label = (verb) => `${verb} ${model.name} version ${v.version}`;
  if (v.status === "ready" && !aliases.includes("production")) {
    actions.append(h("button", {type: "button", "aria-label": label("Promote to production:"),
      onclick: () => write("promote", model, v)}, "Promote to production"));
  }
  if (v.status === "ready") {
    actions.append(h("button", {type: "button", "aria-label": label("Archive"),
      onclick: () => write("archive", model, v)}, "Archive"));
  }
  actions.append(h("button", {type: "button", class: "danger", "aria-label": label("Delete"),
    onclick: (event) => confirmDelete(event.currentTarget, model, v)}, "Delete"));
  return h("tr", {dataset: {version: v.version}},
    h("th", {scope: "row"}, h("a", {href: link}, `v${v.version}`)),
    h("td", {}, v.status), h("td", {class: "aliases"}, aliases.join(", ") || "–"),
    h("td", {}, when(v.created_at)), h("td", {}, h("code", {title: v.sha256}, v.sha256.slice(0, 12))),
    actions);
}

function confirmDelete(button, model, v) {
  const cell = button.parentElement;
  const ask = h("span", {class: "confirm", role: "group", "aria-label": "Confirm the deletion"},
    `Delete v${v.version} and its weights? `,
    h("button", {type: "button", class: "danger", onclick: () => write("delete", model, v)},
      `Yes, delete v${v.version}`),
    h("button", {type: "button", onclick: () => ask.remove()}, "Keep it"));
  cell.append(ask);
  ask.querySelector("button").focus();
}

async function write(action, model, v) {
  const base = `/v1/registry/models/${modelPath(model.name)}/-`;
  const calls = {
    promote: () => request(`${base}/aliases/production`, {method: "PUT", body: {version: v.version}}),
    archive: () => request(`${base}/versions/${v.version}/archive`, {method: "POST"}),
    delete: () => request(`${base}/versions/${v.version}`, {method: "DELETE"}),
  };
  const done = {promote: "production now points at", archive: "archived", delete: "deleted"};
  try {
    await calls[action]();
  } catch (err) {
    notify(err.explain ? err.explain() : String(err));
    return;
  }
  notify(`${model.name}: ${done[action]} v${v.version}`, "ok");
  await loadModels();
  await showModel(model.name, action === "delete" ? null : open.version, {quiet: true});
}

// --- a version's lineage -----------------------------------------------------------------

function lineage(model, v) {
  const lin = v.lineage;
  const metrics = {...lin.metrics};
  const curve = metrics.training_curve;
  delete metrics.training_curve;
  const gate = metrics.gate;
  delete metrics.gate;
  return h("section", {class: "lineage", "aria-labelledby": "lineage-title"},
    h("h4", {id: "lineage-title"}, `${model.name} v${v.version}: lineage`),
    h("dl", {class: "facts"},
      fact("status", v.status), fact("sha256", h("code", {}, v.sha256)),
      fact("size", `${v.size_bytes} bytes`), fact("created", when(v.created_at)),
      fact("seed", lin.seed ?? "–"), fact("code version", lin.code_version),
      fact("registered by", lin.registered_by),
      fact("parents", lin.parents.length ? h("ul", {class: "plain"}, lin.parents.map(parentLink)) : "none")),
    h("h5", {}, "Training curve"), curveView(model, v, curve, metrics.curve),
    h("h5", {}, "Gate"), gate ? keyValues(`Gate of v${v.version}`, gate) : h("p", {class: "muted"}, "no gate recorded"),
    h("h5", {}, "Training config"), keyValues(`Config of v${v.version}`, lin.config),
    Object.keys(metrics).length ? [h("h5", {}, "Other metrics"), keyValues(`Metrics of v${v.version}`, metrics)] : null);
}

function parentLink(ref) {
  const cut = ref.lastIndexOf("/");
  const [name, version] = [ref.slice(0, cut), ref.slice(cut + 1)];
  return h("li", {}, h("a", {href: `#/registry?model=${encodeURIComponent(name)}&version=${version}`}, ref));
}

function curveView(model, v, curve, summary) {
  if (!curve || !curve.steps || !curve.steps.length) {
    const text = summary && summary.points
      ? `Only a summary was registered with this version: first ${num(summary.first)}, best ${num(summary.best)}, final ${num(summary.final)} over ${summary.points} points.`
      : "No training curve was registered with this version.";
    return h("p", {class: "muted"}, text);
  }
  const title = `Mean episode return of ${model.name} v${v.version} during training`;
  return h("figure", {class: "curve"},
    lineChart(title, curve.steps, [{name: "mean return", values: curve.mean_return, colour: "#1f5fa0"}],
      {xLabel: "training step", yLabel: "mean return"}),
    h("figcaption", {}, title),
    dataTable("Training curve", ["step", "mean return", "loss"],
      curve.steps.map((s, i) => [s, num(curve.mean_return[i], 3), num(curve.loss[i], 4)])));
}

function flatten(object, prefix = "") {
  return Object.entries(object || {}).flatMap(([key, value]) =>
    value && typeof value === "object" && !Array.isArray(value)
      ? flatten(value, `${prefix}${key}.`)
      : [[`${prefix}${key}`, Array.isArray(value) ? value.join(", ") : String(value)]]);
}

function keyValues(caption, object) {
  const rows = flatten(object);
  if (!rows.length) return h("p", {class: "muted"}, "none");
  return h("table", {class: "kv"}, h("caption", {class: "visually-hidden"}, caption),
    h("tbody", {}, rows.map(([k, v]) => h("tr", {}, h("th", {scope: "row"}, k), h("td", {}, v)))));
}
