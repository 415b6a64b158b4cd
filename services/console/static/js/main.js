// The page's frame: the three views behind hash routes, the token form and the notice line.
//   #/registry[?model=NAME&version=V]   #/jobs[?job=ID]   #/episodes[?env=...&seed=...]

import {setToken, token} from "./api.js";
import {$, fill} from "./dom.js";
import * as episodes from "./episodes.js";
import * as jobs from "./jobs.js";
import * as registry from "./registry.js";
import {notify} from "./shared.js";

const VIEWS = {registry, jobs, episodes};
let current = null;
let routes = 0; // route() calls so far: only the latest may report its failure

function parseHash() {
  const raw = location.hash.replace(/^#\/?/, "");
  const [name, query = ""] = raw.split("?");
  return {name: VIEWS[name] ? name : "registry", params: new URLSearchParams(query)};
}

async function route() {
  const mine = ++routes;
  const {name, params} = parseHash();
  for (const [view, module] of Object.entries(VIEWS)) {
    const section = $(`#view-${view}`);
    const active = view === name;
    section.hidden = !active;
    const link = document.querySelector(`nav a[data-view="${view}"]`);
    if (active) link.setAttribute("aria-current", "page");
    else link.removeAttribute("aria-current");
    if (!active && current === view) module.hide();
  }
  current = name;
  document.title = `coexist console: ${name}`;
  try {
    await VIEWS[name].show(params);
  } catch (err) {
    // a view opened before the token changed (or the hash) may fail late: not worth a notice
    if (mine === routes) notify(err.explain ? err.explain() : String(err));
  }
}

function showTokenState() {
  fill($("#token-state"), token() ? "token set for this tab" : "no token: reads only, where the server allows");
}

function setUpToken() {
  $("#token").value = token();
  showTokenState();
  $("#token-form").addEventListener("submit", (event) => {
    event.preventDefault();
    setToken($("#token").value.trim());
    showTokenState();
    notify(null);
    route();
  });
  $("#token-forget").addEventListener("click", () => {
    $("#token").value = "";
    setToken("");
    showTokenState();
    route();
  });
}

setUpToken();
window.addEventListener("hashchange", route);
route();
