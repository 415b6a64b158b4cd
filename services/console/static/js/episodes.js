// The live-episode view: the server plays the episode (GET /v1/console/episode, one JSON line
// per step) and this page draws it as the lines arrive; pause, step, step back, replay, and a
// link whose URL holds the seed and every setting.

import {stream} from "./api.js";
import {$, fill} from "./dom.js";
import * as form from "./episode_form.js";
import {createLane} from "./lanes.js";
import {envs, notify} from "./shared.js";

let ready = false;
let playing = null; // the query string of the episode on screen
let episode = null; // {header, frames, laneFrames, lanes, ended, abort}
let cursor = 0;
let running = false;
let timer = null;

export async function show(params) {
  if (!ready) {
    form.setUp(await envs(), (query) => { location.hash = `#/episodes?${query}`; });
    setUpPlayer();
    ready = true;
  }
  if (!params.has("env")) return;
  const query = form.fromParams(params);
  if (query.toString() !== playing) start(query);
}

export function hide() {
  pause();
}

function start(query) {
  if (episode) episode.abort.abort();
  playing = query.toString();
  const abort = new AbortController();
  episode = {header: null, frames: [], laneFrames: [], lanes: [], ended: false, abort};
  cursor = 0;
  const link = $("#pl-link");
  link.href = `${location.origin}${location.pathname}#/episodes?${playing}`;
  fill($("#pl-summary"), "the server is playing the episode …");
  fill($("#lanes"));
  const player = $("#player");
  player.hidden = false;
  player.dataset.frames = "0";
  player.dataset.ended = "false";
  const current = episode;
  stream(`/v1/console/episode?${playing}`, (line) => receive(current, line), abort.signal)
    .catch((err) => {
      if (err.name === "AbortError") return;
      notify(err.explain ? err.explain() : String(err));
      fill($("#pl-summary"), "the episode could not be played");
    });
  play();
}

function receive(ep, line) {
  if (ep !== episode) return;
  if (line.type === "episode") {
    ep.header = line;
    ep.lanes = line.settings.methods.map((method, k) => createLane(line, k, method));
    ep.laneFrames = ep.lanes.map(() => []);
    fill($("#lanes"), ep.lanes.map((lane) => lane.root));
    notify(null);
  } else if (line.type === "frame") {
    line.lanes.forEach((lf, k) => {
      const frames = ep.laneFrames[k];
      frames.push(lf || frames[frames.length - 1]); // an ended lane keeps its last frame
    });
    ep.frames.push(line);
    $("#pl-time").max = String(ep.frames.length - 1);
    $("#player").dataset.frames = String(ep.frames.length);
    if (ep.frames.length === 1) render();
  } else if (line.type === "end") {
    ep.ended = true;
    $("#player").dataset.ended = "true";
    fill($("#pl-summary"), line.lanes.map((lane) =>
      `${lane.method.toUpperCase()}: ${lane.length} steps, team return ${lane.team_return.toFixed(2)}`)
      .join(" · "));
  } else if (line.type === "error") {
    notify(`The episode stopped: ${line.error.message}`);
  }
}

/** Draw every lane at `cursor`. */
function render() {
  if (!episode || !episode.frames.length) return;
  cursor = Math.max(0, Math.min(cursor, episode.frames.length - 1));
  episode.lanes.forEach((lane, k) => {
    const frames = episode.laneFrames[k];
    lane.draw(frames[cursor], frames.slice(0, cursor + 1));
  });
  $("#pl-time").value = String(cursor);
  const total = episode.ended ? ` of ${episode.frames.length - 1}` : "";
  fill($("#pl-status"), `step ${cursor}${total}`);
  $("#player").dataset.t = String(cursor);
}

function play() {
  running = true;
  fill($("#pl-play"), "Pause");
  clearInterval(timer);
  timer = setInterval(advance, 1000 / Number($("#pl-speed").value));
}

function pause() {
  running = false;
  fill($("#pl-play"), "Play");
  clearInterval(timer);
  timer = null;
}

function advance() {
  if (!episode) return;
  if (cursor < episode.frames.length - 1) {
    cursor += 1;
    render();
  } else if (episode.ended) {
    pause();
  }
}

function step(delta) {
  pause();
  cursor += delta;
  render();
}

function setUpPlayer() {
  $("#pl-play").addEventListener("click", () => (running ? pause() : play()));
  $("#pl-step").addEventListener("click", () => step(1));
  $("#pl-back").addEventListener("click", () => step(-1));
  $("#pl-replay").addEventListener("click", () => {
    cursor = 0;
    render();
    play();
  });
  $("#pl-time").addEventListener("input", (event) => {
    pause();
    cursor = Number(event.target.value);
    render();
  });
  $("#pl-speed").addEventListener("change", () => running && play());
  $("#player").addEventListener("keydown", (event) => {
    if (event.target.closest("input, select, button, a")) return;
    const keys = {" ": () => (running ? pause() : play()), ArrowRight: () => step(1),
      ArrowLeft: () => step(-1)};
    if (keys[event.key]) {
      event.preventDefault();
      keys[event.key]();
    }
  });
}
