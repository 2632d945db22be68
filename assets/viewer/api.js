// The viewer's one HTTP client: every call goes through `api`, so every
// failure shows the API's own error message.

export class ApiError extends Error {}

/**
 * POST (with `body`) or GET `path`; throws ApiError with the API's message.
 * A `body` that is an ArrayBuffer (a PLY file) goes as it is, with `type`;
 * anything else as JSON.
 */
export async function api(path, body, type = 'application/json') {
  const raw = body instanceof ArrayBuffer;
  const init = body === undefined
    ? { method: 'GET' }
    : { method: 'POST', headers: { 'Content-Type': type }, body: raw ? body : JSON.stringify(body) };
  let response;
  try {
    response = await fetch(path, init);
  } catch (e) {
    throw new ApiError(`${path}: the server did not answer (${e.message})`);
  }
  let payload = null;
  try {
    payload = await response.json();
  } catch {
    // not JSON: reported below
  }
  if (!response.ok) {
    const err = payload && payload.error;
    const text = err ? `${err.code}: ${err.message}` : `HTTP ${response.status}`;
    throw new ApiError(`${path} → ${response.status} ${text}`);
  }
  if (payload === null) throw new ApiError(`${path}: the answer is not JSON`);
  return payload;
}
