// The episode settings form <-> the query of /v1/console/episode (also the page's URL, so a
// link reproduces an episode). Goals, methods and the agent limit come from GET /v1/envs.

import {$, fill, h} from "./dom.js";

const PARAMS = ["env", "ego_goal", "partners", "infer", "methods", "seed", "max_steps", "temperature"];
let envList = [];

export function setUp(envs, onSubmit) {
  envList = envs;
  const select = $("#ep-env");
  fill(select, envs.map((env) => h("option", {value: env.name}, env.name)));
  select.addEventListener("change", () => fillForEnv(envOf(select.value)));
  $("#ep-add-partner").addEventListener("click", () => {
    const env = envOf(select.value);
    addPartner(env, env.goals[(partnerRows().length + 1) % env.goals.length], false);
    partnerRows().at(-1)?.querySelector("select").focus();
  });
  $("#episode-form").addEventListener("submit", (event) => {
    event.preventDefault();
    onSubmit(toParams());
  });
  fillForEnv(envs[0]);
}

function envOf(name) {
  return envList.find((env) => env.name === name) || envList[0];
}

function options(goals, chosen) {
  return goals.map((goal) => h("option", {value: goal, selected: goal === chosen}, goal));
}

/** The form for `env`: ego and one partner on the catalogue's first goals; its methods. */
function fillForEnv(env, {ego = env.goals[0], partners = [[env.goals[1 % env.goals.length], false]],
  methods = null} = {}) {
  $("#ep-env").value = env.name;
  fill($("#ep-ego"), options(env.goals, ego));
  fill($("#ep-partner-list"));
  for (const [goal, inferred] of partners) addPartner(env, goal, inferred);
  $("#ep-add-partner").disabled = partnerRows().length >= env.max_agents - 1;
  const preferred = methods || env.methods.filter((m) => m === "sl" || m === "aail");
  const checked = preferred.length ? preferred : env.methods.slice(0, 1);
  fill($("#ep-method-list"), env.methods.map((method) => {
    const id = `ep-method-${method}`;
    return h("span", {class: "check"},
      h("input", {type: "checkbox", id, name: "methods", value: method,
        checked: checked.includes(method)}),
      h("label", {for: id}, method.toUpperCase()));
  }));
}

function partnerRows() {
  return [...$("#ep-partner-list").children];
}

function addPartner(env, goal, inferred) {
  const list = $("#ep-partner-list");
  if (list.children.length >= env.max_agents - 1) return;
  const n = list.children.length + 1;
  const [selectId, inferId] = [`ep-partner-${n}`, `ep-infer-${n}`];
  const row = h("li", {class: "partner-row"},
    h("label", {for: selectId}, `Agent ${n}'s goal`),
    h("select", {id: selectId, class: "partner-goal"}, options(env.goals, goal)),
    h("span", {class: "check"},
      h("input", {type: "checkbox", id: inferId, class: "partner-infer", checked: inferred}),
      h("label", {for: inferId}, "ego infers it")),
    h("button", {type: "button", class: "link-button", "aria-label": `Remove agent ${n}`,
      onclick: () => removePartner(env, row)}, "Remove"));
  list.append(row);
  $("#ep-add-partner").disabled = list.children.length >= env.max_agents - 1;
}

/** Remove a partner row; the others are renumbered (agent j is the j-th partner). */
function removePartner(env, removed) {
  const kept = partnerRows().filter((row) => row !== removed).map((row) =>
    [row.querySelector(".partner-goal").value, row.querySelector(".partner-infer").checked]);
  fill($("#ep-partner-list"));
  for (const [goal, inferred] of kept) addPartner(env, goal, inferred);
  $("#ep-add-partner").disabled = false;
  $("#ep-add-partner").focus();
}

/** The form as the episode's query. */
export function toParams() {
  const params = new URLSearchParams();
  params.set("env", $("#ep-env").value);
  params.set("ego_goal", $("#ep-ego").value);
  const rows = partnerRows();
  params.set("partners", rows.map((row) => row.querySelector(".partner-goal").value).join(","));
  params.set("infer", rows.map((row, i) => (row.querySelector(".partner-infer").checked ? i + 1 : null))
    .filter((i) => i !== null).join(","));
  const methods = [...document.querySelectorAll("#ep-method-list input:checked")].map((i) => i.value);
  params.set("methods", methods.join(","));
  params.set("seed", $("#ep-seed").value || "0");
  params.set("max_steps", $("#ep-steps").value || "200");
  const temperature = $("#ep-temperature").value.trim();
  if (temperature) params.set("temperature", temperature);
  return params;
}

/** Fill the form from a query (a link); only known parameters are kept, in a fixed order. */
export function fromParams(params) {
  const env = envOf(params.get("env"));
  const goals = (params.get("partners") || "").split(",").filter(Boolean);
  const inferred = new Set((params.get("infer") || "").split(",").filter(Boolean).map(Number));
  const methods = (params.get("methods") || "").split(",").filter(Boolean);
  fillForEnv(env, {ego: params.get("ego_goal") || env.goals[0],
    partners: goals.map((goal, i) => [goal, inferred.has(i + 1)]), methods});
  $("#ep-seed").value = params.get("seed") || "0";
  $("#ep-steps").value = params.get("max_steps") || "200";
  $("#ep-temperature").value = params.get("temperature") || "";
  const kept = new URLSearchParams();
  for (const key of PARAMS) if (params.has(key)) kept.set(key, params.get(key));
  return kept;
}
