// What every view uses: the server's environments and the notice line.

import {request, token} from "./api.js";
import {$, fill} from "./dom.js";

let envsPromise = null;
let envsToken = null; // the token envsPromise's request was sent with

/** GET /v1/envs once per token: goals, action meanings and methods come from the server. A
 * request still in flight with another token (or none) is not reused: its refusal would
 * answer the view the new token opens. */
export function envs() {
  if (envsPromise === null || envsToken !== token()) {
    envsToken = token();
    const mine = request("/v1/envs").then((body) => body.envs, (err) => {
      if (envsPromise === mine) envsPromise = null; // ask again next time
      throw err;
    });
    envsPromise = mine;
  }
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
