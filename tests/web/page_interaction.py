#!/usr/bin/env python3
"""The web page's interactive plots in headless Chromium (issue 16 points 8 and 9), driven with a
real mouse over the DevTools protocol (cdp.py):

  page_interaction.py --chromium BIN --server URL --profile DIR sweep JOB_ID [--screenshot F] [--frf-screenshot F]
  page_interaction.py --chromium BIN --server URL --profile DIR diagnose JOB_ID --downloads DIR

sweep: the page at /?job=ID draws the saturation map and both FRF families with uPlot. The point of
the up-sweep family that stands farthest from the other amplitudes' curves is chosen from the job's
points as the REST API gives them; the mouse is moved onto it (and onto its cell of the map), and
the readout must show its f, V, |H|, phase, peak-force ratio, branch and stability to the 4
significant digits the page prints. Its amplitude's button is then clicked: the curve must be gone
from both families (the series hidden, and the canvas pixel at the point no longer its colour, as it
was before) and the readout at the same place must name another amplitude; a second click shows it
again. Screenshots (optional): the page with the readout, and the server's SVG FRF family (/frf?format=svg).

diagnose: the finished diagnose job's page shows its conclusion, the diagnosed model's thresholds as
a plot whose hover readout gives the thresholds of threshold_shift.csv at the hovered frequency, the
report in a frame, and a "download model.json" button whose file equals /v1/jobs/ID/report/model.json.

Both: nothing on the console (no uncaught exception, no CSP refusal, no failed load)."""

import argparse
import csv
import io
import json
import math
import os
import sys
import time
import urllib.request

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from cdp import Chromium, CdpError  # noqa: E402


def fail(message):
    print("FAIL: " + message, file=sys.stderr)
    sys.exit(1)


def api(server, path, text=False):
    with urllib.request.urlopen(server + path, timeout=30) as response:
        body = response.read().decode()
    return body if text else json.loads(body)


def phase_rad(re, im):  # the page's and the server's phase: rad on (-pi/2, 3 pi/2]
    rad = math.atan2(im, re)
    while rad <= -math.pi / 2:
        rad += 2 * math.pi
    while rad > 3 * math.pi / 2:
        rad -= 2 * math.pi
    return rad


def same_to_4_digits(shown, expected):
    return abs(shown - expected) <= 5.01e-4 * abs(expected) + 1e-12


def readout_fields(browser, element_id):
    return browser.evaluate(
        f"Object.fromEntries([...document.querySelectorAll('#{element_id} [data-field]')]"
        ".map(e => [e.dataset.field, e.textContent]))")


def check_readout(fields, point, where):
    """The readout against the point's row from the REST API."""
    expected = {
        "f": point["frequency_hz"],
        "V": point["amplitude_v"],
        "|H|": math.hypot(point["h_re_n_per_v"], point["h_im_n_per_v"]),
        "phase": phase_rad(point["h_re_n_per_v"], point["h_im_n_per_v"]),
        "peak force / first harmonic": point["peak_force_n"] / point["first_harmonic_force_n"],
    }
    for name, value in expected.items():
        if name not in fields:
            fail(f"{where}: the readout has no {name}: {fields}")
        shown = float(fields[name].split()[0])
        if not same_to_4_digits(shown, value):
            fail(f"{where}: the readout shows {name} = {fields[name]}, the REST API's point has {value!r}")
    if fields.get("branch") != point["branch"]:
        fail(f"{where}: branch {fields.get('branch')!r}, expected {point['branch']!r}")
    stability = "stable" if point["stable"] else "unstable"
    if fields.get("stability") != stability:
        fail(f"{where}: stability {fields.get('stability')!r}, expected {stability!r}")


def plot_point(browser, plot, x, y):
    """Viewport coordinates of the value (x, y) on a plot, scrolled into view."""
    return browser.evaluate(
        f"(() => {{ const u = strokelabPlots.{plot}; u.root.scrollIntoView({{block: 'nearest'}});"
        f" const r = u.over.getBoundingClientRect();"
        f" return [r.left + u.valToPos({x!r}, 'x'), r.top + u.valToPos({y!r}, 'y')]; }})()")


def canvas_pixel(browser, plot, x, y):
    return browser.evaluate(
        f"(() => {{ const u = strokelabPlots.{plot};"
        f" return [...u.ctx.getImageData(Math.round(u.valToPos({x!r}, 'x', true)), Math.round(u.valToPos({y!r}, 'y', true)), 1, 1).data]; }})()")


def rgb_of(css):  # "rgb(r,g,b)"
    return [int(v) for v in css[css.index("(") + 1:css.index(")")].split(",")]


def colour_distance(a, b):
    return sum(abs(a[k] - b[k]) for k in range(3))


def console_self_check(browser):
    """The console check sees an uncaught error, so that a silent pass means a clean page."""
    browser.navigate("data:text/html,<script>undefinedFunction()</script>")
    deadline = time.monotonic() + 20
    while not any("undefinedFunction" in p for p in browser.console_problems()) and time.monotonic() < deadline:
        browser.pump(0.1)
    if not any("undefinedFunction" in p for p in browser.console_problems()):
        fail(f"the console check does not see an uncaught error: {browser.console_problems()}")
    browser.events.clear()


def dom_checks(browser, job_id):
    """What the page shows besides its plots (the checks of the former --dump-dom test)."""
    html = browser.evaluate("document.documentElement.outerHTML")
    title = browser.evaluate("document.getElementById('detail-title').textContent")
    if title != f"Job {job_id} (sweep, succeeded)":
        fail(f"the detail title is {title!r}")
    if '<td class="status-succeeded">succeeded</td>' not in html:
        fail("the job list does not show the succeeded job")
    titles = browser.evaluate("[...document.querySelectorAll('#detail .u-title')].map(e => e.textContent)")
    for wanted in ("Stroke saturation, up-sweep branch", "First-order FRF |H|, up-sweep branch",
                   "First-order FRF |H|, down-sweep branch"):
        if not any(t.startswith(wanted) for t in titles):
            fail(f"no plot titled {wanted!r}: {titles}")
    if browser.evaluate("document.querySelectorAll('#detail canvas').length") < 3:
        fail("fewer than 3 plot canvases")
    text = browser.evaluate("document.body.innerText")
    if "Jump (bistable) intervals" not in text and "No jump interval" not in text:
        fail("the jump-interval line is missing")
    if '<details id="spec">' not in html or "mass_kg = 0.032" not in html or " values, " not in text + html:
        fail("the job's grid and model (its resolved spec) are not shown")
    note = browser.evaluate("document.getElementById('jobs-note').textContent")
    if note:
        fail(f"the job list shows a note: {note}")
    for error in ("cannot list jobs", "cannot load the results", "cannot show job", "failed:"):
        if error in text:
            fail(f"the page shows an error: {error} ...")


def sweep_checks(browser, args):
    server, job_id = args.server, args.job
    console_self_check(browser)
    browser.navigate(f"{server}/?job={job_id}")
    browser.wait_for("!!(window.strokelabPlots && strokelabPlots.map && strokelabPlots.frf_up && strokelabPlots.frf_down)",
                     60, "the three plots")
    dom_checks(browser, job_id)
    log("DOM: job list, saturation map and FRF families drawn, jump intervals, grid and model")
    job = api(server, f"/v1/jobs/{job_id}")
    freqs = job["resolved"]["grid"]["frequency_hz"]["values"]
    amps = job["resolved"]["grid"]["amplitude_v"]["values"]
    points = []
    cursor = None
    while True:
        page = api(server, f"/v1/jobs/{job_id}/points?branch=up&limit=10000" + (f"&cursor={cursor}" if cursor else ""))
        points += page["points"]
        cursor = page["next_cursor"]
        if not cursor:
            break
    up = {(p["amplitude_v"], p["frequency_hz"]): p for p in points}
    # Points next to a jump of their amplitude carry the jump's mark (a black dot): not a target.
    jump_ends = [(j["amplitude_v"], e) for j in api(server, f"/v1/jobs/{job_id}/jumps")["jump"]
                 for e in (j["bistable_from_hz"], j["bistable_to_hz"]) if e is not None]
    def at_a_jump(a, jf):
        return any(b == a and freqs[jf - 1] <= e <= freqs[jf + 1] for b, e in jump_ends)
    # The up-sweep point farthest (in |H|) from every other amplitude's point at its frequency.
    best, best_gap = None, -1.0
    for jf, f in enumerate(freqs[1:-1], 1):
        at_f = [(a, up[(a, f)]) for a in amps if (a, f) in up]
        for a, p in at_f:
            if at_a_jump(a, jf):
                continue
            h = math.hypot(p["h_re_n_per_v"], p["h_im_n_per_v"])
            gap = min((abs(h - math.hypot(q["h_re_n_per_v"], q["h_im_n_per_v"])) for b, q in at_f if b != a), default=0.0)
            if gap > best_gap:
                best, best_gap = p, gap
    if best is None or best_gap <= 0:
        fail("no up-sweep point stands apart from the other amplitudes' curves")
    f, a = best["frequency_hz"], best["amplitude_v"]
    h = math.hypot(best["h_re_n_per_v"], best["h_im_n_per_v"])
    ia = amps.index(a)
    log(f"hover target: up-sweep point at {f} Hz, {a} V, |H| = {h:.6g} N/V (next curve {best_gap:.3g} N/V away)")

    # 1. Hover on the up-sweep FRF family.
    x, y = plot_point(browser, "frf_up", f, h)
    browser.mouse("mouseMoved", x, y)
    browser.wait_for("document.querySelector('#readout-frf-up [data-field]') !== null", 10, "the FRF readout")
    check_readout(readout_fields(browser, "readout-frf-up"), best, "FRF up-sweep hover")
    log("FRF hover: the readout matches the REST API's point (f, V, |H|, phase, peak-force ratio, branch, stability)")
    if args.screenshot:
        browser.pump(0.3)
        browser.screenshot(args.screenshot)
        log(f"screenshot: {args.screenshot}")

    # 2. Hover on the same point's cell of the saturation map.
    x, y = plot_point(browser, "map", f, a)
    browser.mouse("mouseMoved", x, y)
    browser.wait_for("document.querySelector('#readout-map [data-field]') !== null", 10, "the map readout")
    check_readout(readout_fields(browser, "readout-map"), best, "saturation map hover")
    log("map hover: the readout matches the same point")

    # 3. Toggling the amplitude hides its curve in both families, and shows it again.
    before = canvas_pixel(browser, "frf_up", f, h)
    colour = rgb_of(browser.evaluate(f"strokelabPlots.frf_up.series[{ia + 1}].stroke()"))
    if colour_distance(before, colour) > 90:
        fail(f"before toggling, the canvas at the point is {before}, not the curve's colour {colour}")
    button = browser.evaluate(
        f"(() => {{ const b = document.querySelectorAll('#amplitudes button[data-amplitude]')[{ia}];"
        f" b.scrollIntoView({{block: 'nearest'}}); const r = b.getBoundingClientRect();"
        f" return [r.left + r.width / 2, r.top + r.height / 2, b.dataset.amplitude]; }})()")
    if float(button[2]) != a:
        fail(f"amplitude button {ia} is for {button[2]} V, not {a} V")
    browser.click(button[0], button[1])
    browser.wait_for(f"!strokelabPlots.frf_up.series[{ia + 1}].show && !strokelabPlots.frf_down.series[{ia + 1}].show", 10,
                     "the amplitude's series to be hidden in both families")
    browser.pump(0.2)
    after = canvas_pixel(browser, "frf_up", f, h)
    if colour_distance(after, colour) <= 90:
        fail(f"after toggling {a} V off, the canvas at its point is still its colour: {after} (curve {colour})")
    x, y = plot_point(browser, "frf_up", f, h)
    browser.mouse("mouseMoved", x, y - 1)
    browser.mouse("mouseMoved", x, y)
    browser.pump(0.2)
    shown = readout_fields(browser, "readout-frf-up")
    if shown.get("V") and same_to_4_digits(float(shown["V"].split()[0]), a):
        fail(f"with {a} V hidden, the readout at its point still shows it: {shown}")
    log(f"toggle: {a} V hidden in both families (canvas {before} -> {after}); the readout there now shows {shown.get('V')}")
    browser.click(button[0], button[1])
    browser.wait_for(f"strokelabPlots.frf_up.series[{ia + 1}].show", 10, "the amplitude to be shown again")

    problems = browser.console_problems()
    if problems:
        fail("console on the page: " + "; ".join(problems))
    log("console: clean")

    if args.auth_url:  # a server with tokens, no token in the page: its 401 message
        browser.navigate(args.auth_url)
        browser.wait_for("document.getElementById('jobs-note') && document.getElementById('jobs-note').textContent"
                         ".startsWith('cannot list jobs: missing bearer token')", 30, "the server's 401 message on the page")
        log("without a token: the page shows the server's 401 message")

    if args.frf_screenshot:  # the server's SVG on its own (Chromium asks for a favicon there: not checked)
        svg = api(server, f"/v1/jobs/{job_id}/frf?format=svg&branch=up", text=True)
        width = int(float(svg.split('width="', 1)[1].split('"', 1)[0]))
        height = int(float(svg.split('height="', 1)[1].split('"', 1)[0]))
        browser.navigate(f"{server}/v1/jobs/{job_id}/frf?format=svg&branch=up")
        browser.wait_for("document.readyState === 'complete' && document.documentElement.localName === 'svg'", 20, "the SVG")
        browser.screenshot(args.frf_screenshot, width, height)
        log(f"screenshot: {args.frf_screenshot} ({width} x {height})")


def progress_shown_as(shown, progress):
    """Whether the page's progress text has the form and count of the status's progress: stage k of N
    where the status has stages, tasks done otherwise."""
    wanted = f" of {progress['stages']}" if "stages" in progress else f" / {progress['total']} tasks"
    return wanted in shown and ("stages" in progress) == (": stage " in shown)


def diagnose_checks(browser, args):
    server, job_id = args.server, args.job
    os.makedirs(args.downloads, exist_ok=True)
    browser.send("Browser.setDownloadBehavior", {"behavior": "allow", "downloadPath": os.path.abspath(args.downloads)},
                 session=False)
    browser.navigate(f"{server}/?job={job_id}")
    # While it runs: the progress as the job status gives it (stage k of N where the status has
    # stages, tasks done otherwise), in the job list and the detail.
    browser.wait_for("!!(document.querySelector('#job-progress') || document.querySelector('iframe.report'))", 60,
                     "the job's progress or its report")
    seen_running = False
    while browser.evaluate("!!document.querySelector('#job-progress')"):
        job = api(server, f"/v1/jobs/{job_id}")
        # (The page drops the element when the job ends, possibly since the check above.)
        shown = browser.evaluate("document.querySelector('#job-progress')?.textContent ?? ''")
        progress = job["progress"]
        if job["status"] not in ("queued", "running"):
            break
        # The page polls each second, so it may show the previous stage or form (a clean-clone run saw
        # the page on "stage 10 of 12" while the status had just left its stages): a mismatch counts
        # only if it is still there after the page's next poll.
        if shown.startswith(job["status"]) and not progress_shown_as(shown, progress):
            browser.pump(1.5)
            job = api(server, f"/v1/jobs/{job_id}")
            shown, progress = browser.evaluate("document.querySelector('#job-progress')?.textContent ?? ''"), job["progress"]
            if job["status"] in ("queued", "running") and shown.startswith(job["status"]) and \
                    not progress_shown_as(shown, progress):
                fail(f"the running job's progress shows {shown!r}, its status has {progress}")
        if shown.startswith(job["status"]):
            if not seen_running:
                log(f"running: the page shows {shown!r}")
            seen_running = True
        browser.pump(0.3)
    if not seen_running:
        log("the job had finished before the page showed it running: progress not checked")
    browser.wait_for("!!document.querySelector('iframe.report')", 120, "the diagnosis report's frame")
    result = api(server, f"/v1/jobs/{job_id}/result")
    body = browser.evaluate("document.getElementById('detail').innerText")
    if result["conclusion"][:40] not in body:
        fail(f"the conclusion is not shown: {body[:400]}")
    if not browser.evaluate("document.querySelector('iframe.report').srcdoc.includes('<h2 id=\"maps\">')"):
        fail("the report in the frame has no maps section")
    # The diagnosed model's thresholds: hover the first frequency with a diagnosed grazing amplitude.
    shifts = list(csv.DictReader(io.StringIO(api(server, f"/v1/jobs/{job_id}/report/threshold_shift.csv", text=True))))
    with_value = [s for s in shifts if s["grazing_diagnosed_v"] != ""]
    if not with_value:  # nothing missing: the diagnosis computed no map, and the page says so
        if "No saturation map of the diagnosed model" not in body or browser.evaluate("!!strokelabPlots.diagnosed_map"):
            fail("threshold_shift.csv has no thresholds, and the page does not say that there is no map")
        log("no map of the diagnosed model (nothing missing), and the page says so")
    else:
        s = with_value[len(with_value) // 2]
        f, v = float(s["frequency_hz"]), float(s["grazing_diagnosed_v"])
        browser.wait_for("!!strokelabPlots.diagnosed_map", 10, "the diagnosed model's threshold plot")
        x, y = plot_point(browser, "diagnosed_map", f, v)
        browser.mouse("mouseMoved", x, y)
        browser.pump(0.2)
        shown = browser.evaluate("document.getElementById('readout-diagnosed-map').textContent")
        numbers = [float(t) for t in shown.replace("→", " ").replace("(", " ").split() if t.replace(".", "", 1).replace("-", "", 1).isdigit()]
        expected = [float(s[k]) for k in ("frequency_hz", "grazing_base_v", "grazing_diagnosed_v")]
        if len(numbers) < 3 or not all(same_to_4_digits(n, e) for n, e in zip(numbers[:3], expected)):
            fail(f"the threshold readout at {f} Hz shows {shown!r}, threshold_shift.csv has {s}")
        log(f"diagnosed map hover: {shown}")
    # The model file: the button's download equals the service's model.json.
    button = browser.evaluate(
        "(() => { const b = [...document.querySelectorAll('#detail button')].find(b => b.textContent === 'download model.json');"
        " if (!b) return null; b.scrollIntoView({block: 'nearest'}); const r = b.getBoundingClientRect();"
        " return [r.left + r.width / 2, r.top + r.height / 2]; })()")
    if not button:
        fail("no 'download model.json' button")
    browser.click(button[0], button[1])
    path = os.path.join(args.downloads, f"job-{job_id}-model.json")
    deadline = time.monotonic() + 20
    while not (os.path.exists(path) and os.path.getsize(path) > 0) and time.monotonic() < deadline:
        browser.pump(0.2)
    if not os.path.exists(path):
        fail(f"the model file was not downloaded (files: {os.listdir(args.downloads)})")
    with open(path) as downloaded:
        if json.load(downloaded) != api(server, f"/v1/jobs/{job_id}/report/model.json"):
            fail("the downloaded model.json differs from /v1/jobs/ID/report/model.json")
    log("model.json: downloaded, equal to /report/model.json")
    problems = browser.console_problems()
    if problems:
        fail("console on the page: " + "; ".join(problems))
    log("console: clean")


T0 = time.monotonic()


def log(message):
    print(f"[{time.monotonic() - T0:5.1f} s] {message}")


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--chromium", required=True)
    parser.add_argument("--server", required=True)
    parser.add_argument("--profile", required=True)
    parser.add_argument("kind", choices=["sweep", "diagnose"])
    parser.add_argument("job", type=int)
    parser.add_argument("--screenshot")
    parser.add_argument("--frf-screenshot")
    parser.add_argument("--downloads")
    parser.add_argument("--auth-url")
    parser.add_argument("--height", type=int, default=1000)
    args = parser.parse_args()
    browser = Chromium(args.chromium, args.profile, 1400, args.height)
    try:
        (sweep_checks if args.kind == "sweep" else diagnose_checks)(browser, args)
    except CdpError as error:
        problems = list(dict.fromkeys(browser.console_problems()))[:5]  # distinct ones, the first few
        fail(str(error) + ("; console: " + "; ".join(problems) if problems else ""))
    finally:
        browser.close()


if __name__ == "__main__":
    main()
