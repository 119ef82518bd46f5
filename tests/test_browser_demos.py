"""The live demos (notebooks 17, 18 and 24) in a real browser: JupyterLab started on localhost for
this test, headless Chromium driven through selenium as a person would use it, in JupyterLab's
default layout (the file browser open in the left sidebar) in a 1280x800 window (a 1280x657 page).

For each notebook: open it (the first by its URL, the second from the file browser with a double
click, in the same page), run all cells from the Run menu, check that no cell shows an error
or a warning, that no notification (JupyterLab's "official Jupyter news?" question: switched off by
the settings override the package installs, ``lab_settings/overrides.d``) is shown, that the demo
(controls and image) fits the window, that the image is shown pixel for pixel in the width the
notebook gives it (``kfcal_helpers.demos.NOTEBOOK_WIDTH_PX``) and its smallest text, in points at the
figure's dpi (``kfcal_helpers.demos.smallest_text``), is at least ``MIN_TEXT_PX`` on screen, and that
no control's text is cut; then press an arrow key
on a slider and tick a checkbox with the mouse (in notebook 24, which has none: click UKF, then EKF),
and check that the image changes and still no error appears; in notebook 18 also switch to the UKF, press End on the Q slider and untick the
bearing UGV->UAV (where the UKF has lost positive definiteness): a figure or a one-line message,
never a traceback.  The round trip from the key press or click to the new image (its ``load`` event,
timed in the page) and the sizes measured are written to ``benchmarks/browser_roundtrip.json`` (a
per-run file, not committed).  Screenshots of the window after running all cells and after using
the demo go to a temporary folder, printed and named in that file; on a failure a screenshot and the
page's HTML go to ``build/browser_failures/``.

Needs Chromium and chromedriver (Debian: ``apt-get install chromium chromium-driver``); the test
is skipped, with the reason, when they are not found.  Set ``KFCAL_CHROMIUM`` /
``KFCAL_CHROMEDRIVER`` to use other binaries.
"""

from __future__ import annotations

import datetime as dt
import json
import os
import platform
import secrets
import shutil
import socket
import statistics
import subprocess
import sys
import time
import urllib.request
from contextlib import contextmanager
from pathlib import Path

import pytest
from chromium import CHROMEDRIVER, CHROMIUM, start

from kfcal_helpers.calibration.demos import calibration_controls
from kfcal_helpers.coop.demos import coop_controls
from kfcal_helpers.demos import MIN_TEXT_PX, NOTEBOOK_WIDTH_PX

ROOT = Path(__file__).resolve().parents[1]
NOTEBOOKS = {"17": "17_calibration_live_demo.ipynb", "18": "18_coop_live_demo.ipynb", "24": "24_orbit_live_demo.ipynb"}
BENCH_FILE = ROOT / "benchmarks" / "browser_roundtrip.json"
FAILURES = ROOT / "build" / "browser_failures"
WINDOW = (1280, 800)
KEY_PRESSES = 4  # slider steps timed per notebook



pytestmark = pytest.mark.skipif(
    CHROMIUM is None or CHROMEDRIVER is None,
    reason=("real-browser test of the live demos skipped: no Chromium/chromedriver found "
            f"(chromium: {CHROMIUM or 'missing'}, chromedriver: {CHROMEDRIVER or 'missing'}; "
            "Debian: apt-get install chromium chromium-driver)"))


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture(scope="module")
def lab(tmp_path_factory):
    """JupyterLab on a free localhost port, serving copies of notebooks 17, 18 and 24 (the browser's
    autosave never touches the committed files), with its own runtime, config and settings dirs."""
    tmp = tmp_path_factory.mktemp("jupyterlab")
    root = tmp / "root"
    root.mkdir()
    for name in NOTEBOOKS.values():
        shutil.copy(ROOT / "notebooks" / name, root / name)
    config = tmp / "config"
    config.mkdir()
    # a student's JupyterLab: empty user config, settings and workspaces (the default layout, the file
    # browser open); the news question is switched off by the settings override this package installs
    env = {**os.environ, "JUPYTER_RUNTIME_DIR": str(tmp / "runtime"), "JUPYTER_CONFIG_DIR": str(config),
           "JUPYTER_DATA_DIR": str(tmp / "data"), "JUPYTERLAB_SETTINGS_DIR": str(tmp / "settings"),
           "JUPYTERLAB_WORKSPACES_DIR": str(tmp / "workspaces"), "KFCAL_QUIET": "1"}
    port, token = _free_port(), secrets.token_hex(16)
    log = open(tmp / "jupyterlab.log", "w")
    proc = subprocess.Popen(
        [sys.executable, "-m", "jupyterlab", "--no-browser", "--allow-root", "--ip=127.0.0.1", f"--port={port}",
         "--ServerApp.port_retries=0", f"--IdentityProvider.token={token}", f"--ServerApp.root_dir={root}"],
        cwd=root, env=env, stdout=log, stderr=subprocess.STDOUT)
    url = f"http://127.0.0.1:{port}"
    try:
        deadline = time.monotonic() + 90
        while True:
            try:
                with urllib.request.urlopen(f"{url}/api/status?token={token}", timeout=5):
                    break
            except OSError:
                if proc.poll() is not None or time.monotonic() > deadline:
                    log.flush()
                    pytest.fail(f"JupyterLab did not start: {(tmp / 'jupyterlab.log').read_text()[-2000:]}")
                time.sleep(0.5)
        yield {"url": url, "token": token, "log": tmp / "jupyterlab.log"}
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
        log.close()


@pytest.fixture(scope="module")
def browser(tmp_path_factory):
    driver = start(WINDOW, tmp_path_factory.mktemp('chromium-profile'))
    try:
        driver.set_window_size(*WINDOW)
        yield driver
    finally:
        driver.quit()


@pytest.fixture(scope="module")
def roundtrips():
    """Round trips measured by the tests of this module, written to BENCH_FILE at the end."""
    results = {}
    yield results
    if results:
        BENCH_FILE.parent.mkdir(exist_ok=True)
        chromium = subprocess.run([CHROMIUM, "--version"], capture_output=True, text=True).stdout.strip()
        BENCH_FILE.write_text(json.dumps({
            "what": "round trip in JupyterLab + headless Chromium: key press on a slider / click on a checkbox "
                    "-> the demo's new image loaded in the page, ms",
            "date": dt.datetime.now(dt.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
            "machine": f"{platform.machine()}, {os.cpu_count()} cores, {platform.system()}",
            "browser": chromium, "window": f"{WINDOW[0]}x{WINDOW[1]}",
            "results": results}, indent=2) + "\n")


@pytest.fixture(scope="module")
def screenshots(tmp_path_factory, roundtrips):
    """Where the window's screenshots (1280x800) go: a temporary folder, printed and named in BENCH_FILE."""
    shots = tmp_path_factory.mktemp("demo-screenshots")
    print(f"screenshots of the demos in JupyterLab: {shots}")
    roundtrips["screenshots"] = str(shots)
    return shots


@contextmanager
def _screenshot_on_failure(driver, name):
    try:
        yield
    except BaseException:
        FAILURES.mkdir(parents=True, exist_ok=True)
        stamp = time.strftime("%Y%m%d-%H%M%S")
        shot = FAILURES / f"{name}-{stamp}.png"
        try:
            driver.save_screenshot(str(shot))
            (FAILURES / f"{name}-{stamp}.html").write_text(driver.page_source)
            print(f"browser test failed: screenshot {shot}", file=sys.stderr)
        except Exception as error:  # the browser itself may be gone
            print(f"browser test failed; no screenshot ({error})", file=sys.stderr)
        raise


def _wait(driver, condition, timeout, what):
    """Poll ``condition(driver)`` until it returns something truthy; fail naming ``what``."""
    deadline = time.monotonic() + timeout
    while True:
        value = condition(driver)
        if value:
            return value
        if time.monotonic() > deadline:
            pytest.fail(f"timed out after {timeout} s waiting for {what}")
        time.sleep(0.1)


_ERRORS_JS = """
const [root] = arguments, out = [];
for (const el of root.querySelectorAll(
        '.jp-OutputArea-output[data-mime-type="application/vnd.jupyter.stderr"], .jp-OutputArea-output .ansi-red-fg')) {
    out.push(el.innerText.slice(0, 300));
}
for (const el of root.querySelectorAll('.jp-OutputArea-output')) {
    if (el.innerText.includes('Traceback') || el.innerText.includes('Warning:')) out.push(el.innerText.slice(0, 300));
}
return out;
"""

_PROMPTS_JS = """
return Array.from(arguments[0].querySelectorAll('.jp-CodeCell .jp-InputArea-prompt')).map(e => e.textContent.trim());
"""

# timestamps, in the page, of the last key press / mouse press and of the first load of a new image after it
_TIMING_JS = """
const img = arguments[0];
window.__kf = {start: null, loaded: null, src: img.src};
const start = () => { window.__kf.start = performance.now(); window.__kf.loaded = null; window.__kf.src = img.src; };
document.addEventListener('keydown', start, true);
document.addEventListener('mousedown', start, true);
img.addEventListener('load', () => {
    if (window.__kf.start !== null && window.__kf.loaded === null && img.src !== window.__kf.src) {
        window.__kf.loaded = performance.now();
    }
});
"""

# the rectangles of the demo's parts after scrolling it to the top of the notebook, and the part of
# the window where the notebook shows its cells (below JupyterLab's menu and toolbar, above its status bar)
_RECTS_JS = """
const [box] = arguments;
box.scrollIntoView({block: 'start'});
const scroller = box.closest('.jp-WindowedPanel-outer') || box.closest('.jp-Notebook');
const v = scroller.getBoundingClientRect();
const parts = [box, ...box.querySelectorAll('.widget-slider, .widget-checkbox, .widget-toggle-buttons, img.widget-image')];
return {window: [window.innerWidth, window.innerHeight],
        view: {left: Math.max(v.left, 0), top: Math.max(v.top, 0), right: Math.min(v.right, window.innerWidth),
               bottom: Math.min(v.bottom, window.innerHeight)},
        rects: parts.map(e => { const r = e.getBoundingClientRect();
            return {what: e.className.toString().split(' ').filter(c => c.startsWith('widget-')).join(' ') || e.tagName,
                    left: r.left, top: r.top, right: r.right, bottom: r.bottom}; })};
"""


_FILE_BROWSER_JS = """
const fb = document.getElementById('filebrowser');
return fb && fb.offsetParent !== null ? fb.getBoundingClientRect().width : 0;
"""

# JupyterLab's toast notifications (the news question is one)
_TOASTS_JS = """
return Array.from(document.querySelectorAll('.Toastify__toast')).map(e => {
    const r = e.getBoundingClientRect();
    return {text: e.innerText.trim().slice(0, 200), left: r.left, top: r.top, right: r.right, bottom: r.bottom};
});
"""

# the demo's image as shown (CSS px) and as encoded (its PNG's pixels), the width the notebook gives
# its output, and every control's text: its font size and whether it is cut (ellipsis or clipped)
_LAYOUT_JS = """
const [box, img] = arguments;
const r = img.getBoundingClientRect(), out = img.closest('.jp-OutputArea-output').getBoundingClientRect();
const texts = Array.from(box.querySelectorAll(
        '.widget-label, .widget-readout, .widget-checkbox span, .widget-checkbox label, .widget-toggle-button'))
    .filter(e => e.innerText.trim()).map(e => ({text: e.innerText.trim(),
        font_px: parseFloat(getComputedStyle(e).fontSize), cut: e.scrollWidth > e.clientWidth + 1}));
return {shown: [r.width, r.height], natural: [img.naturalWidth, img.naturalHeight], output_width: out.width,
        texts: texts};
"""


# the notebook panel in front (JupyterLab keeps the notebooks opened before in the page, hidden) if its tab
# is labelled with the file's name; read from the tab, not from the panel's text, which WebDriver takes
# seconds to gather from a long notebook
_PANEL_JS = """
const [name] = arguments;
const shown = Array.from(document.querySelectorAll('.jp-NotebookPanel:not(.lm-mod-hidden)'));
if (shown.length !== 1) return null;
const tab = document.querySelector(`.lm-TabBar-tab[data-id="${shown[0].id}"] .lm-TabBar-tabLabel`);
return tab && tab.textContent.trim() === name && shown[0].querySelector('.jp-Cell') ? shown[0] : null;
"""


def _open(driver, lab, name):
    """Open ``name``: from JupyterLab's file browser with a double click when JupyterLab is already open in
    the window (as a student opens a second notebook), else by its URL; return its panel once shown."""
    from selenium.webdriver.common.action_chains import ActionChains
    from selenium.webdriver.common.by import By

    if driver.current_url.startswith(lab["url"]):
        items = [e for e in driver.find_elements(By.CSS_SELECTOR, "#filebrowser .jp-DirListing-itemText")
                 if e.text.strip() == name]
        assert len(items) == 1, f"{name} is listed {len(items)} times in JupyterLab's file browser"
        ActionChains(driver).double_click(items[0]).perform()
    else:
        driver.get(f"{lab['url']}/lab/tree/{name}?token={lab['token']}")
        lab["page_loaded"] = time.monotonic()
    return _wait(driver, lambda d: d.execute_script(_PANEL_JS, name), 90, f"{name} to open")


def _open_and_run_all(driver, lab, name):
    from selenium.webdriver.common.by import By

    panel = _open(driver, lab, name)
    idle = '.jp-Notebook-ExecutionIndicator[data-status="idle"]'
    _wait(driver, lambda d: panel.find_elements(By.CSS_SELECTOR, idle), 90, "the kernel to be idle")
    # JupyterLab's default layout, as a student sees it: the file browser open in the left sidebar
    assert driver.execute_script(_FILE_BROWSER_JS) > 100, "the file browser is not open in the left sidebar"
    # Run > Run All Cells, with the mouse
    run_menu = [e for e in driver.find_elements(By.CSS_SELECTOR, ".lm-MenuBar-item") if e.text.strip() == "Run"]
    assert run_menu, "no Run menu in JupyterLab's menu bar"
    run_menu[0].click()
    item = _wait(driver, lambda d: [e for e in d.find_elements(By.CSS_SELECTOR, ".lm-Menu-item .lm-Menu-itemLabel")
                                    if e.text.strip() == "Run All Cells"], 10, "the Run All Cells menu item")
    item[0].click()
    # the number of code cells from the notebook file: JupyterLab may not have put every cell in the page yet
    cells = json.loads((ROOT / "notebooks" / name).read_text(encoding="utf-8"))["cells"]
    n_code = sum(c["cell_type"] == "code" for c in cells)

    def finished(d):
        prompts = d.execute_script(_PROMPTS_JS, panel)
        done = len(prompts) == n_code and all(p.startswith("[") and p[1:-2].strip().isdigit() for p in prompts)
        return done and panel.find_elements(By.CSS_SELECTOR, idle)

    _wait(driver, finished, 240, f"all {n_code} code cells of {name} to run")
    counts = [int(p[1:-2]) for p in driver.execute_script(_PROMPTS_JS, panel)]
    assert counts == list(range(1, n_code + 1)), f"cells ran out of order: {counts}"
    image = _wait(driver, lambda d: [e for e in panel.find_elements(By.CSS_SELECTOR, "img.widget-image")
                                     if (e.get_attribute("src") or "").startswith("blob:")], 60, "the demo's image")
    assert len(image) == 1, f"{len(image)} widget images in {name}, expected the demo's one"
    return panel, image[0]


def _no_errors(driver, panel, when):
    errors = driver.execute_script(_ERRORS_JS, panel)
    assert not errors, f"error output {when}: {errors}"


def _fits_window(driver, image):
    """The whole demo (every control and the image) is visible at once in the notebook's area."""
    from selenium.webdriver.common.by import By

    box = image.find_element(By.XPATH, "ancestor::div[contains(@class, 'widget-box')][last()]")
    got = driver.execute_script(_RECTS_JS, box)
    assert got["window"][0] <= WINDOW[0] and got["window"][1] <= WINDOW[1], got["window"]
    v = got["view"]
    outside = [r for r in got["rects"] if r["left"] < v["left"] - 0.5 or r["top"] < v["top"] - 0.5
               or r["right"] > v["right"] + 0.5 or r["bottom"] > v["bottom"] + 0.5]
    assert len(got["rects"]) >= 5 and not outside, (  # the box, its image and at least three controls
        f"demo not within the notebook's visible area {v} of the {got['window']} window: {outside}")


def _round_trip(driver, image, action, what, timeout=30.0) -> float:
    """Do ``action()``; wait for the new image; return the page-timed round trip in ms and
    check that the pixels changed."""
    before = image.screenshot_as_png
    action()
    _wait(driver, lambda d: d.execute_script("return window.__kf.loaded !== null"), timeout, f"a new image after {what}")
    ms = driver.execute_script("return window.__kf.loaded - window.__kf.start")
    time.sleep(0.1)  # let the frame with the new image be painted
    assert image.screenshot_as_png != before, f"the image did not change after {what}"
    return round(float(ms), 1)


def _slider_handle(panel, description):
    from selenium.webdriver.common.by import By

    for slider in panel.find_elements(By.CSS_SELECTOR, ".widget-slider"):
        label = slider.find_elements(By.CSS_SELECTOR, ".widget-label")
        if label and label[0].text.strip() == description:
            return slider.find_element(By.CSS_SELECTOR, ".noUi-handle")
    pytest.fail(f"no slider {description!r}")


def _checkbox(panel, description):
    from selenium.webdriver.common.by import By

    for box in panel.find_elements(By.CSS_SELECTOR, ".widget-checkbox"):
        if box.text.strip() == description:
            return box.find_element(By.CSS_SELECTOR, "input[type=checkbox]")
    pytest.fail(f"no checkbox {description!r}")


def _ukf_at_large_q(driver, panel, image):
    """Notebook 18: the UKF with Q / Qtrue at the slider's end and without the bearing UGV->UAV,
    where the UKF has lost positive definiteness: a figure or a one-line message, no traceback."""
    from selenium.webdriver.common.by import By
    from selenium.webdriver.common.keys import Keys

    c = coop_controls()
    ukf = [b for b in panel.find_elements(By.CSS_SELECTOR, ".widget-toggle-button") if b.text.strip() == "UKF"]
    assert ukf, "no UKF button"
    _round_trip(driver, image, ukf[0].click, "a click on UKF")
    _round_trip(driver, image, lambda: _slider_handle(panel, c["q_scale"].description).send_keys(Keys.END),
                "End on the Q slider")
    _round_trip(driver, image, _checkbox(panel, c["m0"].description).click, "unticking the bearing UGV->UAV")
    line = panel.find_element(By.CSS_SELECTOR, ".widget-html").text.strip()
    assert "\n" not in line and (line.startswith("UKF, Q = 100 Qtrue") or "positive definite" in line
                                  or "not finite" in line), line
    return line


def _live_figure(nb):
    """The live view's figure as the notebook builds it (its style, ``LIVE_FIGSIZE``, the controls'
    defaults), drawn: the image the browser shows for these settings has its pixel size."""
    from matplotlib.figure import Figure

    from kfcal_helpers.style import use_style

    use_style()
    if nb == "17":
        from kfcal_helpers.calibration.demos import LIVE_FIGSIZE, CalibrationDemoFigure, compute_calibration_demo

        view = CalibrationDemoFigure(Figure(figsize=LIVE_FIGSIZE))
        view.update(compute_calibration_demo(outage=(12.0, 18.0)))
    elif nb == "18":
        from kfcal_helpers.coop import simulate
        from kfcal_helpers.coop.demos import LIVE_FIGSIZE, CoopDemoFigure, compute_coop_demo

        view = CoopDemoFigure(Figure(figsize=LIVE_FIGSIZE))
        view.update(compute_coop_demo(simulate().log(), "ekf"))
    else:
        from kfcal_helpers.orbit import simulate
        from kfcal_helpers.orbit.demos import LIVE_FIGSIZE, OrbitDemoFigure, compute_orbit_demo, precompute_orbit_demo

        view = OrbitDemoFigure(Figure(figsize=LIVE_FIGSIZE))
        view.update(compute_orbit_demo(precompute_orbit_demo(simulate().log())))
    view.draw()
    return view.fig


def _show(driver, image):
    """Scroll the demo to the top of the notebook's area (JupyterLab scrolls to the active cell)."""
    from selenium.webdriver.common.by import By

    box = image.find_element(By.XPATH, "ancestor::div[contains(@class, 'widget-box')][last()]")
    driver.execute_script("arguments[0].scrollIntoView({block: 'start'});", box)
    time.sleep(0.3)


def _readable(driver, nb, image, shots):
    """No toast (the news question) anywhere, the figure's smallest text at least MIN_TEXT_PX on screen,
    every control's text whole and at least MIN_TEXT_PX; returns what was measured."""
    from selenium.webdriver.common.by import By

    from kfcal_helpers.demos import smallest_text

    box = image.find_element(By.XPATH, "ancestor::div[contains(@class, 'widget-box')][last()]")
    got = driver.execute_script(_LAYOUT_JS, box, image)
    toasts = driver.execute_script(_TOASTS_JS)
    fig = _live_figure(nb)
    points, text = smallest_text(fig)
    width_px = fig.canvas.get_width_height()[0]
    scale = got["shown"][0] / got["natural"][0]
    on_screen = points * fig.dpi / 72 * scale
    measured = {"file_browser_px": round(driver.execute_script(_FILE_BROWSER_JS), 1),
                "output_width_px": round(got["output_width"], 1),
                "image_px": got["natural"], "image_shown_px": [round(v, 1) for v in got["shown"]],
                "smallest_figure_text": {"text": text, "points": points, "dpi": fig.dpi,
                                         "on_screen_px": round(on_screen, 2)},
                "smallest_control_text_px": min(t["font_px"] for t in got["texts"]), "toasts": toasts,
                "screenshots": str(shots)}
    print(f"notebook {nb}: {json.dumps(measured)}")
    assert not toasts, f"a notification is shown over the notebook (the news question?): {toasts}"
    assert got["output_width"] >= NOTEBOOK_WIDTH_PX - 0.5, (
        f"JupyterLab gives the notebook's output {got['output_width']:.0f} px, less than the "
        f"{NOTEBOOK_WIDTH_PX} px the live figures are sized for (kfcal_helpers.demos.NOTEBOOK_WIDTH_PX)")
    assert got["natural"][0] == width_px, (
        f"the browser shows a {got['natural']} px image, the live view's figure is {width_px} px wide")
    assert on_screen >= MIN_TEXT_PX, (
        f"the figure's smallest text ({text!r}, {points:g} pt at {fig.dpi:g} dpi) is {on_screen:.1f} px on "
        f"screen: the {got['natural'][0]} px image is shown {got['shown'][0]:.0f} px wide in the "
        f"{got['output_width']:.0f} px the notebook gives its output")
    small = [t for t in got["texts"] if t["font_px"] < MIN_TEXT_PX or t["cut"]]
    assert not small, f"controls' texts cut or smaller than {MIN_TEXT_PX} px: {small}"
    return measured


def _toggle(panel, text):
    from selenium.webdriver.common.by import By

    for button in panel.find_elements(By.CSS_SELECTOR, ".widget-toggle-button"):
        if button.text.strip() == text:
            return button
    pytest.fail(f"no toggle button {text!r}")


def _drive(driver, lab, nb, slider, checkbox, roundtrips, shots):
    """Run the demo of notebook ``nb``, press the right arrow on ``slider`` and click ``checkbox`` twice (a
    checkbox's description, or ``("UKF", "EKF")``: a click on each of these toggle buttons), timing each."""
    from selenium.webdriver.common.keys import Keys

    name = NOTEBOOKS[nb]
    with _screenshot_on_failure(driver, f"nb{nb}"):
        panel, image = _open_and_run_all(driver, lab, name)
        _no_errors(driver, panel, f"after running all cells of {name}")
        _fits_window(driver, image)
        # the news question, when it is asked, appears a moment after the page has loaded
        time.sleep(max(0.0, lab["page_loaded"] + 2 - time.monotonic()))
        _show(driver, image)
        driver.save_screenshot(str(shots / f"nb{nb}-after-run-all.png"))
        measured = _readable(driver, nb, image, shots)
        driver.execute_script(_TIMING_JS, image)
        handle = _slider_handle(panel, slider)
        keys = [_round_trip(driver, image, lambda: handle.send_keys(Keys.ARROW_RIGHT), f"a key press on {slider!r}")
                for _ in range(KEY_PRESSES)]
        if isinstance(checkbox, tuple):
            clicks = [_round_trip(driver, image, _toggle(panel, text).click, f"a click on {text!r}") for text in checkbox]
        else:
            box = _checkbox(panel, checkbox)
            clicks = [_round_trip(driver, image, box.click, f"a click on {checkbox!r}") for _ in range(2)]
            assert box.is_selected()  # unticked, then ticked again
        if nb == "18":
            roundtrips["notebook 18: line shown for the UKF at Q / Qtrue 100 without the bearing UGV->UAV"] = \
                _ukf_at_large_q(driver, panel, image)
        _no_errors(driver, panel, f"after moving {slider!r} and clicking {checkbox!r} in {name}")
        _fits_window(driver, image)
        assert not driver.execute_script(_TOASTS_JS), "a notification appeared while the demo was used"
        _show(driver, image)
        driver.save_screenshot(str(shots / f"nb{nb}-after-use.png"))
    roundtrips[f"notebook {nb}"] = {
        "slider": slider, "key_press_ms": keys, "key_press_median_ms": statistics.median(keys),
        "checkbox": checkbox, "click_ms": clicks, "layout": measured}
    return keys, clicks


def test_calibration_demo_in_the_browser(lab, browser, roundtrips, screenshots):
    c = calibration_controls()
    _drive(browser, lab, "17", c["W"].description, c["outage_on"].description, roundtrips, screenshots)


def test_coop_demo_in_the_browser(lab, browser, roundtrips, screenshots):
    c = coop_controls()
    _drive(browser, lab, "18", c["q_scale"].description, c["m1"].description, roundtrips, screenshots)


def test_orbit_demo_in_the_browser(lab, browser, roundtrips, screenshots):
    """Notebook 24: the time slider (each key press moves the pass geometry by one 10 s step) and the
    EKF/UKF switch."""
    c = _orbit_descriptions()
    _drive(browser, lab, "24", c["t"], ("UKF", "EKF"), roundtrips, screenshots)


def _orbit_descriptions() -> dict:
    """The orbit demo's control descriptions, by name (its controls need the precomputed runs: built on a short log)."""
    from kfcal_helpers.orbit import OrbitParams, simulate
    from kfcal_helpers.orbit.demos import orbit_controls, precompute_orbit_demo

    runs = precompute_orbit_demo(simulate(OrbitParams(n_steps=20)).log())
    return {name: control.description for name, control in orbit_controls(runs).items()}
