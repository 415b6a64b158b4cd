// The server's REST API, called with the token the user typed (kept for this tab only).

const TOKEN_KEY = "coexist.token";

export function token() {
  return sessionStorage.getItem(TOKEN_KEY) || "";
}

export function setToken(value) {
  if (value) sessionStorage.setItem(TOKEN_KEY, value);
  else sessionStorage.removeItem(TOKEN_KEY);
}

/** An HTTP error: the server answers RFC 9457 problem details
 * ({type, title, status, detail, code, field}); older servers {error: {code, message, field}}. */
export class ApiError extends Error {
  constructor(status, code, message, field) {
    super(message);
    this.status = status;
    this.code = code;
    this.field = field;
  }

  /** What to tell the user: the refusal spelled out for 401 / 403. */
  explain() {
    if (this.status === 401) {
      return `Refused (401): this server needs a token for that. ${this.message}`;
    }
    if (this.status === 403) {
      return `Refused (403): the token is not valid for that. ${this.message}`;
    }
    const field = this.field ? ` [${this.field}]` : "";
    return `Error ${this.status}${field}: ${this.message}`;
  }
}

function headers(extra = {}) {
  const out = {Accept: "application/json", ...extra};
  const t = token();
  if (t) out.Authorization = `Bearer ${t}`;
  return out;
}

async function failure(response) {
  let body = null;
  try {
    body = await response.json();
  } catch {
    body = null;
  }
  return fromBody(response.status, response.statusText, body);
}

/** The ApiError an error body describes: problem details, else the older shape. */
export function fromBody(status, statusText, body) {
  const old = body && typeof body.error === "object" && body.error ? body.error : null;
  const problem = old ? {} : (body && typeof body === "object" ? body : {});
  const error = old || {code: problem.code, message: problem.detail || problem.title,
    field: problem.field};
  return new ApiError(status, error.code || "http_error",
    error.message || statusText || "request failed", error.field || null);
}

/** JSON request; resolves to the parsed body (null for 204), rejects with an ApiError. */
export async function request(path, {method = "GET", body = undefined} = {}) {
  const init = {method, headers: headers(body === undefined ? {} : {"Content-Type": "application/json"})};
  if (body !== undefined) init.body = JSON.stringify(body);
  const response = await fetch(path, init);
  if (!response.ok) throw await failure(response);
  return response.status === 204 ? null : response.json();
}

/** GET an NDJSON stream; `onLine(object)` for each line as it arrives. */
export async function stream(path, onLine, signal) {
  const response = await fetch(path, {headers: headers({Accept: "application/x-ndjson"}), signal});
  if (!response.ok) throw await failure(response);
  const reader = response.body.getReader();
  const decoder = new TextDecoder();
  let buffered = "";
  for (;;) {
    const {value, done} = await reader.read();
    if (done) break;
    buffered += decoder.decode(value, {stream: true});
    let newline;
    while ((newline = buffered.indexOf("\n")) >= 0) {
      const line = buffered.slice(0, newline);
      buffered = buffered.slice(newline + 1);
      if (line.trim()) onLine(JSON.parse(line));
    }
  }
  if (buffered.trim()) onLine(JSON.parse(buffered));
}

/** Model names keep their slashes in registry paths. */
export function modelPath(name) {
  return name.split("/").map(encodeURIComponent).join("/");
}
