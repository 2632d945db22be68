"""Drives the viewer (`GET /viewer`) in headless Chromium against a running
treemanip server: the page loads without console errors, the three flows
(prediction vs truth, policy affordances, planned arm motion) draw, and a
bad tree shows the API's own error message.

Usage: viewer_browser.py URL [--screenshots DIR] [--urdf FILE --urdf-nodes N]
Exit status 0 when every check passes; prints one line per check.
Needs Debian's `chromium` and `chromium-driver` and `pip install selenium`.
"""

import argparse
import json
import os
import shutil
import sys
import time
import urllib.request

from selenium import webdriver
from selenium.webdriver.chrome.service import Service
from selenium.webdriver.common.by import By
from selenium.webdriver.support.ui import Select, WebDriverWait

# A tree the server rejects: node 2's parent does not exist.
BAD_TREE = {
    "positions": [[0, 0, 0], [0, 0, 0.4], [0.1, 0, 0.7]],
    "parents": [None, 0, 7],
    "radius": [None, 0.01, 0.006],
}


def driver():
    options = webdriver.ChromeOptions()
    for arg in [
        "--headless=new",
        "--no-sandbox",
        "--disable-dev-shm-usage",
        "--window-size=1400,900",
        # WebGL without a GPU: SwiftShader (its deprecation notice is not an
        # error of the page).
        "--enable-unsafe-swiftshader",
        "--use-angle=swiftshader",
        "--ignore-gpu-blocklist",
    ]:
        options.add_argument(arg)
    binary = os.environ.get("CHROMIUM") or shutil.which("chromium") or shutil.which("chromium-browser")
    if binary:
        options.binary_location = binary
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    chromedriver = os.environ.get("CHROMEDRIVER") or shutil.which("chromedriver")
    return webdriver.Chrome(service=Service(executable_path=chromedriver), options=options)


class Check:
    def __init__(self, browser, shots):
        self.browser = browser
        self.shots = shots
        self.failed = []

    def ok(self, condition, what):
        print(("ok   " if condition else "FAIL ") + what, flush=True)
        if not condition:
            self.failed.append(what)
        return condition

    def js(self, script, *args):
        return self.browser.execute_script(script, *args)

    def wait_idle(self, timeout=60):
        """Until the page's current action finished (data-busy back to 0)."""
        time.sleep(0.05)
        WebDriverWait(self.browser, timeout).until(
            lambda b: b.execute_script("return document.body.dataset.busy") == "0"
        )

    def click(self, element_id, timeout=60):
        self.browser.find_element(By.ID, element_id).click()
        self.wait_idle(timeout)

    def error_text(self):
        box = self.browser.find_element(By.ID, "error")
        return box.text if box.is_displayed() else ""

    def console_errors(self):
        severe = [e for e in self.browser.get_log("browser") if e["level"] == "SEVERE"]
        # A failed API call is logged by Chromium as a network error of the
        # resource; the page itself must not log errors.
        return [e for e in severe if "Failed to load resource" not in e["message"]]

    def drawn(self, what):
        px = self.js("return window.treemanipViewer.nonBackgroundPixels()")
        share = px["count"] / max(px["total"], 1)
        self.ok(share > 0.005, f"{what}: canvas not blank ({100 * share:.1f} % of pixels drawn)")

    def shot(self, name):
        if self.shots:
            path = os.path.join(self.shots, name)
            self.browser.save_screenshot(path)
            print(f"     screenshot {path}")


def run(url, shots, urdf, urdf_nodes, ply=None, ply_points=None):
    browser = driver()
    c = Check(browser, shots)
    try:
        browser.get(url + "/viewer")
        WebDriverWait(browser, 30).until(
            lambda b: b.execute_script("return document.body.dataset.ready") == "1"
        )
        c.ok(True, "page loaded, module scripts ran")
        c.ok(c.console_errors() == [], f"no console errors on load {c.console_errors()}")

        # Flow 0: an example tree from the generator.
        browser.find_element(By.ID, "example-nodes").clear()
        browser.find_element(By.ID, "example-nodes").send_keys("15")
        browser.find_element(By.ID, "example-seed").clear()
        browser.find_element(By.ID, "example-seed").send_keys("3")
        c.click("example-load")
        c.ok(c.js("return document.body.dataset.tree") == "15", "example tree of 15 nodes loaded")
        c.drawn("tree")

        # Flow 1: a push, the forward model's prediction beside the truth.
        Select(browser.find_element(By.ID, "push-node")).select_by_value("9")
        c.click("predict")
        rows = browser.find_elements(By.CSS_SELECTOR, "#error-table tbody tr")
        c.ok(len(rows) == 15, f"per-node error table has a row per node ({len(rows)})")
        layers = c.js("return window.treemanipViewer.layers()")
        c.ok(layers.get("predicted", 0) > 0 and layers.get("truth", 0) > 0, f"predicted and true trees drawn {layers}")
        colours = c.js("return window.treemanipViewer.colours")
        orange = c.js("return window.treemanipViewer.pixelsNear(arguments[0])", colours["predicted"])
        green = c.js("return window.treemanipViewer.pixelsNear(arguments[0])", colours["truth"])
        c.ok(orange > 50 and green > 50, f"prediction and truth visible ({orange} orange, {green} green pixels)")
        status = browser.find_element(By.ID, "predict-status").text
        c.ok("mean error" in status, f"prediction summary: {status!r}")
        c.ok("Peak bending stress" in status and "MPa" in status, f"the truth's peak stress shown: {status!r}")
        c.ok(c.error_text() == "", f"no error shown ({c.error_text()!r})")
        c.shot("viewer_predict.png")

        # Flow 2: the simulated push as target, the policy's affordances.
        c.click("target-from-push")
        c.click("policy")
        items = browser.find_elements(By.CSS_SELECTOR, "#policy-list li")
        c.ok(len(items) == 5, f"top pushes listed ({len(items)})")
        affordance = c.js("return window.treemanipViewer.layers().affordance")
        c.ok(affordance >= 14 + 3, f"affordance colour per node and top-3 arrows drawn ({affordance} objects)")
        c.ok(c.error_text() == "", f"no error shown ({c.error_text()!r})")
        c.drawn("policy")
        c.shot("viewer_policy.png")

        # Flow 3: plan with the physics strategy and play the trajectory.
        Select(browser.find_element(By.ID, "plan-strategy")).select_by_value("physics")
        c.click("plan", timeout=120)
        plan_state = c.js("return document.body.dataset.plan")
        c.ok(plan_state == "planned", f"plan found: {browser.find_element(By.ID, 'plan-status').text!r} {c.error_text()!r}")
        if plan_state == "planned":
            frames = c.js("return window.treemanipViewer.state.poses.poses.length")
            links = c.js("return window.treemanipViewer.layers().arm")
            c.ok(frames > 2 and links >= 8, f"arm drawn from link poses ({links} links, {frames} waypoints)")
            # The last frame: the push done, the tree moved with it.
            c.js("window.treemanipViewer.play(false); window.treemanipViewer.showFrame(1e9)")
            phase = browser.find_element(By.ID, "phase").text
            c.ok(phase.startswith("push"), f"trajectory ends pushing ({phase!r})")
            status = browser.find_element(By.ID, "plan-status").text
            c.ok("(guard)" in status, f"the guard force shown: {status!r}")
            arm = c.js("return window.treemanipViewer.pixelsNear(arguments[0], 40)", colours["arm"])
            c.ok(arm > 200, f"arm visible ({arm} pixels)")
            c.shot("viewer_plan.png")

        # Flow 4: clear a fruit across node 9's branch (selected in flow 1).
        Select(browser.find_element(By.ID, "plan-objective")).select_by_value("clear")
        c.click("plan", timeout=120)
        c.ok(c.error_text() == "", f"no error shown ({c.error_text()!r})")
        region = c.js("return window.treemanipViewer.layers().region")
        c.ok(region == 1, f"the fruit drawn ({region} regions)")
        c.js("window.treemanipViewer.play(false); window.treemanipViewer.showFrame(0)")
        red = c.js("return window.treemanipViewer.pixelsNear(arguments[0], 60)", colours["region"])
        c.ok(red > 50, f"the fruit visible ({red} pixels)")
        status = browser.find_element(By.ID, "plan-status").text
        clear_state = c.js("return document.body.dataset.plan")
        c.ok(
            (clear_state == "planned" and "intrusion into the fruit" in status)
            or (clear_state == "no_plan" and "outcomes" in status),
            f"clear plan reported: {status!r}",
        )
        c.js("window.treemanipViewer.showFrame(1e9)")
        c.shot("viewer_clear.png")
        Select(browser.find_element(By.ID, "plan-objective")).select_by_value("shape")

        if ply:
            browser.find_element(By.ID, "ply-file").send_keys(os.path.abspath(ply))
            c.wait_idle()
            nodes = int(c.js("return document.body.dataset.tree") or 0)
            dots = int(c.js("return document.body.dataset.cloud") or 0)
            c.ok(
                nodes >= 5 and dots == ply_points,
                f"a scanned cloud gives a tree ({nodes} nodes) drawn over its {dots} of {ply_points} points {c.error_text()!r}",
            )
            c.drawn("tree from a cloud")
            c.shot("viewer_cloud.png")

        if urdf:
            browser.find_element(By.ID, "urdf-file").send_keys(os.path.abspath(urdf))
            c.wait_idle()
            got = c.js("return document.body.dataset.tree")
            c.ok(got == str(urdf_nodes), f"URDF upload gives the {urdf_nodes}-node tree (got {got}) {c.error_text()!r}")
            c.drawn("URDF tree")

        # A bad tree: the API's message appears in the page.
        browser.find_element(By.ID, "json-details").click()
        area = browser.find_element(By.ID, "tree-json")
        area.clear()
        c.js("arguments[0].value = arguments[1]", area, json.dumps(BAD_TREE))
        c.click("json-load")
        request = urllib.request.Request(
            url + "/v1/simulate",
            data=json.dumps({"tree": BAD_TREE, "contact_node": 1, "push": [0, 0, 0]}).encode(),
            headers={"Content-Type": "application/json"},
        )
        try:
            urllib.request.urlopen(request)
            expected = None
        except urllib.error.HTTPError as e:
            expected = json.load(e)["error"]["message"]
        shown = c.error_text()
        c.ok(expected is not None and expected in shown, f"bad tree shows the API's message: {shown!r}")
        kept = c.js("return document.body.dataset.tree")
        c.ok(kept == str(urdf_nodes if urdf else 15), f"the loaded tree is kept after a bad one ({kept} nodes)")
        c.ok(c.console_errors() == [], f"no console errors from the page {c.console_errors()}")
    finally:
        browser.quit()
    return c.failed


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("url")
    parser.add_argument("--screenshots")
    parser.add_argument("--urdf", help="a tree URDF to upload through the page")
    parser.add_argument("--urdf-nodes", type=int, help="its node count")
    parser.add_argument("--ply", help="a scanned cloud (PLY) to upload through the page")
    parser.add_argument("--ply-points", type=int, help="its point count")
    args = parser.parse_args()
    if args.screenshots:
        os.makedirs(args.screenshots, exist_ok=True)
    failed = run(args.url.rstrip("/"), args.screenshots, args.urdf, args.urdf_nodes, args.ply, args.ply_points)
    if failed:
        print(f"{len(failed)} checks failed", file=sys.stderr)
        sys.exit(1)
    print("all viewer checks passed")


if __name__ == "__main__":
    main()
