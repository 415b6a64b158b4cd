// One lane of a live episode (one method): the world, each agent's action distribution, the
// ego's blend weights (w_t and each partner's w_i), the beliefs over inferred partners' goals,
// and the rewards and returns so far.

import {bars} from "./charts.js";
import {fill, h, num} from "./dom.js";
import {createWorld} from "./scene.js";

export function createLane(header, k, method) {
  const title = `lane-${k}-title`;
  const label = method.toUpperCase();
  const world = createWorld(header.scene, `World of lane ${label}`);
  const returns = h("p", {class: "lane-returns"});
  const agents = h("div", {class: "agent-panels"});
  const blend = h("div", {class: "blend"});
  const models = h("details", {class: "models"});
  // a wide world (a kitchen) goes above the panels, a square one beside them
  const wide = header.scene.width > 1.5 * header.scene.height;
  const root = h("section", {class: "lane", "aria-labelledby": title, dataset: {method}},
    h("h3", {id: title}, label), returns,
    h("div", {class: wide ? "lane-body wide-world" : "lane-body"},
      h("div", {class: "world-wrap"}, world.svg), h("div", {class: "lane-panels"}, agents, blend)),
    models);

  /** Draw the lane at frame `lf` (its frames up to now in `history`). */
  function draw(lf, history) {
    world.draw(lf, history);
    const team = lf.returns.reduce((a, b) => a + b, 0);
    fill(returns, h("strong", {}, `team return ${num(team)}`), " · ",
      header.agents.map((a, i) => `agent ${i} ${num(lf.returns[i])}`).join(" · "),
      lf.done ? " · episode over" : "");
    fill(agents, header.agents.map((agent) => agentPanel(header, agent, lf)));
    fill(blend, lf.ego ? blendPanel(header, lf.ego) : null);
    if (lf.ego && lf.ego.models) {
      fill(models, h("summary", {}, `networks of the ego (${lf.ego.models.length})`),
        h("p", {class: "muted"}, lf.ego.models.join(", ")));
    }
  }

  return {root, draw};
}

function agentPanel(header, agent, lf) {
  const colour = header.scene.agent_colours[agent.index];
  const swatch = h("span", {class: "swatch", "aria-hidden": "true"});
  swatch.style.background = colour;
  const role = agent.role === "ego" ? "ego" : `partner${agent.inferred ? ", goal inferred by the ego" : ""}`;
  const reward = `reward ${num(lf.rewards[agent.index], 3)}, return ${num(lf.returns[agent.index])}`;
  const policy = lf.policies ? lf.policies[agent.index] : null;
  const name = `agent ${agent.index}: action probabilities`;
  return h("div", {class: "agent-panel", dataset: {agent: agent.index}},
    h("h4", {}, swatch, `agent ${agent.index} · ${agent.goal} · ${role}`),
    h("p", {class: "muted"}, reward),
    policy
      ? bars(name, policy.probs.map((p, a) => ({label: header.action_meanings[a], value: p,
        highlight: a === policy.action, note: a === policy.action ? "taken" : ""})))
      : h("p", {class: "muted"}, "no action: the episode is over"));
}

function blendPanel(header, ego) {
  const weights = [{label: "task (w_t)", value: ego.task_weight},
    ...ego.partner_weights.map((w) => ({label: `partner ${w.index} (w_${w.index})`, value: w.weight}))];
  return [
    h("h4", {}, "Ego's blend"),
    bars("ego's blend weights", weights, {kind: "weight"}),
    h("p", {class: "muted"}, `normalised entropy of the task policy ${num(ego.task_entropy, 3)}`),
    ego.beliefs.map((belief) => beliefPanel(header, belief)),
  ];
}

function beliefPanel(header, belief) {
  const truth = header.agents[belief.index].goal;
  const top = belief.top.map((g) => ({label: g.goal, value: g.prob,
    note: g.goal === truth ? "true" : "", highlight: g.goal === truth}));
  const rest = 1 - belief.top.reduce((sum, g) => sum + g.prob, 0);
  return h("div", {class: "belief", dataset: {partner: belief.index}},
    h("h4", {}, `Belief over agent ${belief.index}'s goal`),
    bars(`belief over agent ${belief.index}'s goal`, [...top, {label: "other goals", value: Math.max(0, rest)}],
      {kind: "belief"}),
    h("p", {class: "muted"}, `entropy ${num(belief.entropy, 3)} nats after ${belief.updates} actions; its goal is ${truth}`));
}
