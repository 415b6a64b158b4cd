// What every view uses: the server's environments and the notice line.

import {request} from "./api.js";
import {$, fill} from "./dom.js";

let envsPromise = null;

/** GET /v1/envs once: goals, action meanings and methods come from the server. */
export function envs() {
  envsPromise ??= request("/v1/envs").then((body) => body.envs, (err) => {
    envsPromise = null; // ask again next time
    throw err;
  });
  return envsPromise;
}

/** Show a message in the alert line (errors) or clear it (null). */
export function notify(message, kind = "error") {
  const notice = $("#notice");
  if (!message) {
    notice.hidden = true;
    fill(notice);
    return;
  }
  notice.className = `notice ${kind}`;
  fill(notice, message);
  notice.hidden = false;
}
