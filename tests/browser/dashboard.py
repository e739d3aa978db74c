#!/usr/bin/env python3
"""The dashboard in a real browser: Playwright for Python driving Debian's Chromium headless
against a coordinator with two local workers (and a third, broken, worker).

It logs in (and fails with a wrong token), submits jobs, sees them listed, watches a job's
tiles fill and its preview change, pauses and resumes it, cancels another, raises a queued
job's priority and sees the queue order change, deletes a finished job and sees its files
gone, and sees the broken worker blocklisted for a job that still completes on the others.
A screenshot of every page goes to --out; any console error fails the test.

    python3 tests/browser/dashboard.py --tessera target/debug/tessera --out /tmp/shots
"""

import argparse
import hashlib
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
import urllib.request
from pathlib import Path

from playwright.sync_api import expect, sync_playwright

ROOT = Path(__file__).resolve().parents[2]
CORNELL = ROOT / "scenes" / "cornell-box" / "scene.json"
CLIENT, WORKER = "browser-client-token", "browser-worker-token"


def store_args(data):
    """--store for the suite's run on PostgreSQL (TESSERA_TEST_POSTGRES): a schema of its own."""
    base = os.environ.get("TESSERA_TEST_POSTGRES")
    if not base:
        return []
    schema = "t_" + hashlib.sha256(str(data).encode()).hexdigest()[:16]
    sep = "&" if "?" in base else "?"
    return ["--store", f"{base}{sep}options=-csearch_path%3D{schema}"]


class Farm:
    def __init__(self, tessera, data):
        self.tessera = tessera
        self.data = data
        self.procs = []
        serve = subprocess.Popen(
            [tessera, "serve", "--local-workers", "2", "--data", str(data), "--listen", "127.0.0.1:0",
             "--client-token", CLIENT, "--worker-token", WORKER, "--lease-seconds", "5"]
            + store_args(data),
            stdout=subprocess.PIPE, stderr=open(data.parent / "serve.log", "w"), text=True)
        self.procs.append(serve)
        line = serve.stdout.readline()
        m = re.search(r"listening on (http://\S+)", line)
        if not m:
            raise SystemExit(f"the coordinator did not start: {line!r}")
        self.url = m.group(1)
        self.env = dict(os.environ, TESSERA_COORDINATOR=self.url, TESSERA_CLIENT_TOKEN=CLIENT)

    def broken_worker(self):
        """A worker that fails every task it takes (a machine with a fault)."""
        p = subprocess.Popen(
            [self.tessera, "worker", "--coordinator", self.url, "--token", WORKER, "--name", "broken",
             "--slots", "1", "--fail-tasks-with", "simulated GPU fault"],
            stdout=subprocess.DEVNULL, stderr=open(self.data.parent / "broken.log", "w"))
        self.procs.append(p)

    def submit(self, name, *args):
        out = subprocess.run(
            [self.tessera, "submit", str(CORNELL), "--name", name, "-q", *args],
            env=self.env, capture_output=True, text=True, check=True).stdout
        return int(re.search(r"job (\d+) queued", out).group(1))

    def api(self, path, method="GET"):
        req = urllib.request.Request(self.url + path, method=method,
                                     headers={"Authorization": f"Bearer {CLIENT}"})
        with urllib.request.urlopen(req, timeout=30) as r:
            body = r.read()
            return json.loads(body) if body else None

    def wait(self, what, predicate, timeout=120):
        start = time.time()
        while time.time() - start < timeout:
            value = predicate()
            if value:
                return value
            time.sleep(0.25)
        raise AssertionError(f"timed out waiting for {what}")

    def stop(self):
        for p in reversed(self.procs):
            p.terminate()
        for p in self.procs:
            try:
                p.wait(timeout=15)
            except subprocess.TimeoutExpired:
                p.kill()


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--tessera", required=True)
    ap.add_argument("--out", required=True, type=Path)
    ap.add_argument("--chromium", default=shutil.which("chromium") or "/usr/bin/chromium")
    args = ap.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    work = Path(tempfile.mkdtemp(prefix="tessera-browser-"))
    farm = Farm(args.tessera, work / "data")
    errors = []
    try:
        with sync_playwright() as p:
            browser = p.chromium.launch(executable_path=args.chromium, args=[
                "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                "--disable-background-networking", "--disable-component-update", "--disable-sync"])
            page = browser.new_page(viewport={"width": 1400, "height": 900})
            page.on("console", lambda m: errors.append(f"console {m.type}: {m.text} ({m.location.get('url')})") if m.type == "error" else None)
            page.on("pageerror", lambda e: errors.append(f"page error: {e}"))
            page.on("dialog", lambda d: d.accept())
            page.set_default_timeout(60_000)
            run(farm, page, args.out)
            browser.close()
    finally:
        farm.stop()
    if errors:
        raise SystemExit("console errors:\n" + "\n".join(errors))
    print("dashboard: every check passed; screenshots in", args.out)


def step(what):
    print("--", what, flush=True)


def run(farm, page, out):
    # Without a session the dashboard sends the browser to log in.
    step("log in")
    page.goto(farm.url + "/")
    expect(page).to_have_url(re.compile(r"/login$"))
    page.screenshot(path=str(out / "login.png"))
    page.fill("#token", "not-the-token")
    page.click("button[type=submit]")
    expect(page.locator(".error")).to_contain_text("not a person's token of this coordinator")
    page.screenshot(path=str(out / "login-failed.png"))
    page.fill("#token", CLIENT)
    page.click("button[type=submit]")
    expect(page).to_have_url(re.compile(r"/$"))
    expect(page.locator("#live")).to_have_text("live")
    expect(page.locator("#whoami")).to_have_text("admin (admin)")

    # A long job to watch, two to reorder, one to cancel, one to finish and delete.
    step("submit jobs")
    watched = farm.submit("watched", "--size", "320x240", "--spp", "512", "--tile", "32")
    cancel_me = farm.submit("cancel me", "--size", "64x64", "--spp", "64")
    first = farm.submit("queued first", "--size", "64x64", "--spp", "16")
    second = farm.submit("queued second", "--size", "64x64", "--spp", "16")
    rows = page.locator("#jobs tbody tr")
    expect(rows).to_have_count(4)
    expect(page.locator(f"tr[data-job='{watched}'] .badge")).to_have_text(re.compile("running|queued"))
    # Who submitted each job: the client token's user.
    expect(page.locator(f"tr[data-job='{watched}'] td.submitter")).to_have_text("admin")
    page.screenshot(path=str(out / "jobs.png"), full_page=True)

    # The queue order: raising the second job's priority puts it before the first.
    step("priority")
    page.select_option("select", "queue")
    order = lambda: page.locator("#jobs tbody tr").evaluate_all("rs => rs.map(r => Number(r.dataset.job))")
    farm.wait("queue order", lambda: order().index(first) < order().index(second))
    page.click(f"tr[data-job='{second}'] button[title='Raise priority']")
    farm.wait("the raised job first", lambda: order().index(second) < order().index(first))
    expect(page.locator(f"tr[data-job='{second}'] [data-priority]")).to_have_text("1")
    page.screenshot(path=str(out / "jobs-queue-order.png"), full_page=True)

    # Cancel one from the list.
    step("cancel")
    page.click(f"tr[data-job='{cancel_me}'] button[data-action=cancel]")
    expect(page.locator(f"tr[data-job='{cancel_me}'] .badge")).to_have_text("cancelled")

    # The watched job: tiles fill, the preview changes; pause holds it, resume goes on.
    step("watch a job")
    page.click(f"a[href='/jobs/{watched}']")
    expect(page).to_have_url(re.compile(rf"/jobs/{watched}$"))
    canvas = page.locator("#tilemap")
    done = lambda: int(canvas.get_attribute("data-done") or 0)
    farm.wait("tiles on the map", lambda: int(canvas.get_attribute("data-tasks") or 0) > 0)
    total = int(canvas.get_attribute("data-tasks"))
    start_done = done()
    farm.wait("tiles to fill", lambda: done() >= start_done + 3)
    preview = page.locator("#preview")
    farm.wait("a preview", lambda: int(preview.get_attribute("data-n") or 0) >= 1)
    first_shot = preview.screenshot()
    n0 = int(preview.get_attribute("data-n"))
    farm.wait("the preview to refresh", lambda: int(preview.get_attribute("data-n") or 0) > n0 + 1)
    page.wait_for_timeout(300)
    assert preview.screenshot() != first_shot, "the preview did not change as results arrived"
    page.screenshot(path=str(out / "job-running.png"), full_page=True)

    step("pause and resume")
    page.click("button[data-action=pause]")
    expect(page.locator(".page-head .badge")).to_have_text("paused")
    # Tasks leased before the pause finish; then nothing more is done.
    farm.wait("leased tasks to finish", lambda: farm.api(f"/v1/jobs/{watched}")["tasks"]["leased"] == 0)
    held = farm.api(f"/v1/jobs/{watched}")["tasks"]["done"]
    time.sleep(2.0)
    assert farm.api(f"/v1/jobs/{watched}")["tasks"]["done"] == held, "a paused job kept rendering"
    page.screenshot(path=str(out / "job-paused.png"), full_page=True)
    page.click("button[data-action=resume]")
    expect(page.locator(".page-head .badge")).to_have_text(re.compile("running|done"))
    farm.wait("the job to go on", lambda: farm.api(f"/v1/jobs/{watched}")["tasks"]["done"] > held)
    assert total > 0

    # A broken worker joins: it fails what it takes, is blocklisted, the job still finishes.
    step("blocklist a broken worker")
    farm.broken_worker()
    farm.wait("the broken worker", lambda: any(w["name"] == "broken" for w in farm.api("/v1/workers")))
    victim = farm.submit("survives a broken worker", "--size", "96x96", "--spp", "32", "--tile", "16",
                         "--priority", "5")
    farm.wait("the victim to finish", lambda: farm.api(f"/v1/jobs/{victim}")["state"] == "done", timeout=240)
    job = farm.api(f"/v1/jobs/{victim}")
    assert [b["worker"] for b in job["blocklist"]] and job["blocklist"][0]["worker"].startswith("broken"), job["blocklist"]
    page.goto(f"{farm.url}/jobs/{victim}")
    expect(page.locator("#blocklist")).to_contain_text("broken")
    expect(page.locator("#attempts")).to_contain_text("simulated GPU fault")
    page.screenshot(path=str(out / "job-blocklist.png"), full_page=True)
    page.click("a[data-nav=workers]")
    broken_row = page.locator("#workers tbody tr", has_text="broken")
    expect(broken_row.locator(".blocked-for", has_text=f"job {victim}")).to_have_count(1)
    page.screenshot(path=str(out / "workers.png"), full_page=True)

    # Delete a finished job from its page: the list loses it, its files go.
    step("delete")
    farm.wait("a job to finish", lambda: farm.api(f"/v1/jobs/{first}")["state"] == "done", timeout=240)
    job_dir = farm.data / "jobs" / str(first)
    assert job_dir.exists(), job_dir
    page.goto(f"{farm.url}/jobs/{first}")
    expect(page.locator(".page-head .badge")).to_have_text("done")
    page.screenshot(path=str(out / "job-done.png"), full_page=True)
    page.click("button[data-action=delete]")
    expect(page).to_have_url(re.compile(r"/$"))
    expect(page.locator(f"tr[data-job='{first}']")).to_have_count(0)
    farm.wait("its files to go", lambda: not job_dir.exists())

    # The API's documentation, browsable.
    step("docs and logout")
    page.goto(farm.url + "/docs/")
    expect(page.locator("#swagger-ui")).to_contain_text("Tessera render farm")
    page.screenshot(path=str(out / "docs.png"))
    page.goto(farm.url + "/")
    page.click("button:has-text('Log out')")
    expect(page).to_have_url(re.compile(r"/login$"))
    page.goto(farm.url + "/workers")
    expect(page).to_have_url(re.compile(r"/login$"))


if __name__ == "__main__":
    sys.exit(main())
