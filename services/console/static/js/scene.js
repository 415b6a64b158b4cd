// Paints an environment's scene (envs/scene.py) as SVG: the static shapes once, then per frame
// the agents' trails, the agents and the moving objects. Knows shapes, not environments.

import {h} from "./dom.js";

/** A world view for one lane. `scene`: the episode header's scene; `name`: for its label. */
export function createWorld(scene, name) {
  const {width, height} = scene;
  const pad = 0.03 * Math.max(width, height);
  const Y = (y) => (scene.y_up ? height - y : y);
  const svg = h("svg", {class: "world", role: "img", "aria-label": name,
    viewBox: `${-pad} ${-pad} ${width + 2 * pad} ${height + 2 * pad}`});
  const layers = ["static", "trails", "agents", "objects"].map((k) => h("g", {class: `layer-${k}`}));
  svg.append(...layers);
  const [staticLayer, trailLayer, agentLayer, objectLayer] = layers;
  for (const shape of scene.shapes) staticLayer.append(drawShape(shape, Y, scene.y_up));

  function draw(frame, history) {
    trailLayer.replaceChildren(...frame.agents.map((agent) => h("polyline", {
      class: "trail", stroke: scene.agent_colours[agent.index],
      points: history.map((f) => {
        const a = f.agents[agent.index];
        return `${a.x},${Y(a.y)}`;
      }).join(" "),
    })));
    agentLayer.replaceChildren(...frame.agents.map((agent) => h("g", {class: "agent"},
      h("circle", {cx: agent.x, cy: Y(agent.y), r: scene.agent_radius,
        fill: scene.agent_colours[agent.index], class: "agent-disc",
        dataset: {agent: agent.index, x: agent.x, y: agent.y, status: agent.status || ""}},
      h("title", {}, agent.label)),
      h("text", {x: agent.x, y: Y(agent.y), "font-size": scene.agent_radius * 1.2,
        class: "agent-index", "aria-hidden": "true"}, String(agent.index)))));
    objectLayer.replaceChildren(...frame.shapes.map((shape) => drawShape(shape, Y, scene.y_up)));
    svg.setAttribute("aria-label", `${name}: ${frame.agents.map((a) => a.label).join("; ")}`);
  }

  return {svg, draw};
}

/** One shape; a rect's (x, y) is its lower-left corner when y points up, else its top-left. */
function drawShape(shape, Y, yUp) {
  const style = {
    fill: shape.fill || "none", stroke: shape.stroke || "none",
    "fill-opacity": shape.opacity ?? 1, class: shape.dash ? "shape dashed" : "shape",
  };
  const title = shape.label ? h("title", {}, shape.label) : null;
  switch (shape.kind) {
  case "rect": {
    const top = yUp ? Y(shape.y + shape.h) : shape.y;
    return h("rect", {x: shape.x, y: top, width: shape.w, height: shape.h, ...style}, title);
  }
  case "circle":
    return h("circle", {cx: shape.x, cy: Y(shape.y), r: shape.r, ...style}, title);
  case "line":
    return h("line", {x1: shape.x, y1: Y(shape.y), x2: shape.x2, y2: Y(shape.y2), ...style}, title);
  case "text":
    return h("text", {x: shape.x, y: Y(shape.y), "font-size": shape.size, class: "shape-text",
      fill: shape.fill || "#222"}, shape.text, title);
  default:
    return h("g", {}, title);
  }
}
