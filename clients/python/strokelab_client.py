"""A client for the strokelab REST service, using only the Python standard library.

    from strokelab_client import Client, StrokelabError
    client = Client("http://127.0.0.1:8080", token=None)
    job_id = client.submit({"kind": "sweep", "model": "paper",
                            "grid": {"frequency_hz": {"from": 5, "points": 117, "spacing": "eq1"},
                                     "amplitude_v": {"from": 0.1, "to": 0.6, "points": 26}}})
    client.wait(job_id, progress=lambda job: print(job["progress"]))
    for point in client.points(job_id, branch="up", amplitude_v=0.5):
        ...
    saturation = client.saturation_map(job_id)   # {"saturation_threshold": [...], "jump": [...]}

Every error reply of the server ({"error": {"code", "message", "field"}}) is raised as a
StrokelabError carrying the HTTP status, code, message and field (a JSON pointer into the job,
or a query parameter's name). Network failures are raised as StrokelabError with code
"unreachable" and status 0.
"""

from __future__ import annotations

import json
import os
import time
import urllib.error
import urllib.parse
import urllib.request
from typing import Any, Callable, Dict, Iterator, Optional

__all__ = ["Client", "StrokelabError", "FINISHED"]

FINISHED = ("succeeded", "failed", "cancelled")


class StrokelabError(Exception):
    """An error reply of the server (or a failure to reach it)."""

    def __init__(self, status: int, code: str, message: str, field: Optional[str] = None):
        self.status = status
        self.code = code
        self.message = message
        self.field = field
        where = f" at {field}" if field else ""
        super().__init__(f"HTTP {status} {code}{where}: {message}")


class Client:
    """One strokelab server. token: a bearer token (read or submit role), default $STROKELAB_TOKEN."""

    def __init__(self, server: str = "http://127.0.0.1:8080", token: Optional[str] = None,
                 timeout_s: float = 60.0):
        self.server = server.rstrip("/")
        self.token = token if token is not None else os.environ.get("STROKELAB_TOKEN") or None
        self.timeout_s = timeout_s

    # --- transport -------------------------------------------------------------------------------

    def request(self, method: str, path: str, body: Any = None, query: Optional[Dict[str, Any]] = None,
                accept: str = "application/json") -> Any:
        """One request; returns the decoded JSON body (or the text for non-JSON replies)."""
        url = self.server + path
        if query:
            pairs = {k: v for k, v in query.items() if v is not None}
            if pairs:
                url += "?" + urllib.parse.urlencode(pairs)
        data = None
        headers = {"Accept": accept}
        if body is not None:
            data = body if isinstance(body, bytes) else json.dumps(body).encode("utf-8")
            headers["Content-Type"] = "application/json"
        if self.token:
            headers["Authorization"] = "Bearer " + self.token
        req = urllib.request.Request(url, data=data, method=method, headers=headers)
        try:
            with urllib.request.urlopen(req, timeout=self.timeout_s) as reply:
                raw = reply.read()
                content_type = reply.headers.get("Content-Type", "")
        except urllib.error.HTTPError as e:
            raise _error_from(e) from None
        except (urllib.error.URLError, OSError) as e:
            reason = getattr(e, "reason", e)
            raise StrokelabError(0, "unreachable", f"cannot reach {self.server}: {reason}") from None
        if not raw:
            return None
        if "application/json" in content_type:
            return json.loads(raw.decode("utf-8"))
        return raw.decode("utf-8")

    # --- jobs ------------------------------------------------------------------------------------

    def submit(self, job: Dict[str, Any]) -> int:
        """Submits a job (dict as in schema/job.schema.json); returns its id."""
        return int(self.request("POST", "/v1/jobs", body=job)["id"])

    def status(self, job_id: int) -> Dict[str, Any]:
        """{"id", "kind", "status", "progress": {"done", "total"}, timings, "error"?}."""
        return self.request("GET", f"/v1/jobs/{int(job_id)}")

    def jobs(self, limit: int = 50) -> Iterator[Dict[str, Any]]:
        """All jobs, newest first (pages through GET /v1/jobs)."""
        before = None
        while True:
            page = self.request("GET", "/v1/jobs", query={"limit": limit, "before": before})
            yield from page["jobs"]
            before = page.get("next_before")
            if before is None:
                return

    def wait(self, job_id: int, progress: Optional[Callable[[Dict[str, Any]], None]] = None,
             poll_s: float = 0.5, timeout_s: Optional[float] = None) -> Dict[str, Any]:
        """Polls until the job finishes; calls progress(status) after each poll. Returns the final
        status (succeeded, failed or cancelled; check "status"). Raises TimeoutError after timeout_s."""
        start = time.monotonic()
        while True:
            job = self.status(job_id)
            if progress is not None:
                progress(job)
            if job["status"] in FINISHED:
                return job
            if timeout_s is not None and time.monotonic() - start > timeout_s:
                raise TimeoutError(f"job {job_id} still {job['status']} after {timeout_s} s")
            time.sleep(poll_s)

    def cancel(self, job_id: int) -> Dict[str, Any]:
        """Cancels a queued or running job; returns its status. A finished job: StrokelabError 409."""
        return self.request("DELETE", f"/v1/jobs/{int(job_id)}")

    # --- results ---------------------------------------------------------------------------------

    def points(self, job_id: int, page_size: int = 1000, **filters: Any) -> Iterator[Dict[str, Any]]:
        """Every steady state of a sweep, one dict per grid point and branch, over all pages.
        filters: frequency_min_hz, frequency_max_hz, amplitude_v, branch (up|down|unstable)."""
        unknown = set(filters) - {"frequency_min_hz", "frequency_max_hz", "amplitude_v", "branch"}
        if unknown:
            raise TypeError(f"unknown filter(s): {', '.join(sorted(unknown))}")
        cursor = None
        while True:
            query = dict(filters, limit=page_size, cursor=cursor)
            page = self.request("GET", f"/v1/jobs/{int(job_id)}/points", query=query)
            yield from page["points"]
            cursor = page.get("next_cursor")
            if cursor is None:
                return

    def points_csv(self, job_id: int, limit: Optional[int] = None, **filters: Any) -> str:
        """Points as CSV text with a header line: every row that passes the filters, or the first
        page of up to limit rows. The whole table is also pandas.read_csv(f"{url}/points?format=csv")."""
        query = dict(filters, format="csv", limit=limit)
        return self.request("GET", f"/v1/jobs/{int(job_id)}/points", query=query, accept="text/csv")

    def thresholds_csv(self, job_id: int) -> str:
        """The saturation threshold per frequency as CSV text (frequency_hz, grazing_amplitude_v,
        lowest_contact_amplitude_v; an empty cell where the stop is not reached)."""
        return self.request("GET", f"/v1/jobs/{int(job_id)}/thresholds", query={"format": "csv"}, accept="text/csv")

    def jumps_csv(self, job_id: int) -> str:
        """The jump (bistable) intervals per amplitude as CSV text."""
        return self.request("GET", f"/v1/jobs/{int(job_id)}/jumps", query={"format": "csv"}, accept="text/csv")

    def saturation_map(self, job_id: int) -> Dict[str, Any]:
        """{"job", "saturation_threshold": [{frequency_hz, grazing_amplitude_v,
        lowest_contact_amplitude_v}], "jump": [{amplitude_v, bistable_from_hz, bistable_to_hz, ...}]}."""
        return self.request("GET", f"/v1/jobs/{int(job_id)}/saturation-map")

    def saturation_map_svg(self, job_id: int) -> str:
        """The saturation map picture (heat map, threshold curves, jump region) as SVG text."""
        return self.request("GET", f"/v1/jobs/{int(job_id)}/saturation-map", query={"format": "svg"},
                            accept="image/svg+xml")

    def frf(self, job_id: int, amplitude_v: float) -> Dict[str, Any]:
        """FRF branches at one of the job's amplitudes: {"amplitude_v", "branches": {"up": [...],
        "down": [...], "unstable": [...]}}, each entry {frequency_hz, h_re_n_per_v, h_im_n_per_v, magnitude_n_per_v}."""
        return self.request("GET", f"/v1/jobs/{int(job_id)}/frf", query={"amplitude_v": repr(float(amplitude_v))})

    def frf_svg(self, job_id: int, branch: str = "up") -> str:
        """|H| against frequency, one line per amplitude, for one branch, as SVG text."""
        return self.request("GET", f"/v1/jobs/{int(job_id)}/frf", query={"format": "svg", "branch": branch},
                            accept="image/svg+xml")

    def health(self) -> Dict[str, Any]:
        return self.request("GET", "/v1/health")


def _error_from(e: urllib.error.HTTPError) -> StrokelabError:
    raw = e.read()
    try:
        error = json.loads(raw.decode("utf-8"))["error"]
        return StrokelabError(e.code, error.get("code", "http_error"), error.get("message", ""), error.get("field"))
    except (ValueError, KeyError, TypeError, AttributeError):
        text = raw.decode("utf-8", "replace").strip()
        return StrokelabError(e.code, "http_error", text or str(e.reason))
