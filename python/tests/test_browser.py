"""The page of `matedit serve` in a real browser (headless chromium through selenium): a
photo uploaded through #file is shown to be pointed at (body data-state "pointing") and,
analysed as it is, decomposed (body data-state "ready", every picture of the
decomposition loads), a preset's full edit is shown and equals what the server returns
for the same request, it changes the object and leaves the background alone, the turn
slider brings a new edit, a second photo's material can be chosen, and a file that is not
an image shows an error. A photo of two objects: analysed as it is, the nets' refusal
shows and asks for a box; a box dragged by mouse shows the object's mask over the photo, a
click on the object refines it, and the photo pointed at is analysed and edited. Skipped
when the
binary, chromium, chromedriver or selenium is missing, unless MATEDIT_REQUIRE_BROWSER=1
(then it fails). The binary: $MATEDIT_BIN, else the newer of target/release/matedit and
target/debug/matedit; the screenshots: $MATEDIT_SCREENSHOT, else tmp_path/page.png, and
$MATEDIT_POINTING_SCREENSHOT, else tmp_path/pointing.png."""

import base64
import io
import json
import os
import re
import shutil
import subprocess
import tarfile
import threading
import time
import urllib.request
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
SAMPLES = ROOT / "python" / "tests" / "data" / "nets_card" / "chunk-000000.tar"
PRESET = "gold-metallic-paint3"
READY_TIMEOUT = 300  # seconds: a debug build decomposes slowly, the more beside the gallery's spheres
EDIT_TIMEOUT = 60


def unavailable(reason):
    if os.environ.get("MATEDIT_REQUIRE_BROWSER") == "1":
        pytest.fail(f"{reason} (and MATEDIT_REQUIRE_BROWSER=1)")
    pytest.skip(reason)


def find_binary():
    env = os.environ.get("MATEDIT_BIN")
    if env:
        if not Path(env).is_file():
            unavailable(f"MATEDIT_BIN={env} does not exist")
        return Path(env)
    found = [p for p in (ROOT / "target/release/matedit", ROOT / "target/debug/matedit") if p.is_file()]
    if not found:
        unavailable("no matedit binary (target/release or target/debug; or set MATEDIT_BIN)")
    return max(found, key=lambda p: p.stat().st_mtime)


def find_browser():
    chromium = next((p for p in ("/usr/bin/chromium", shutil.which("chromium"), shutil.which("chromium-browser"))
                     if p and Path(p).is_file()), None)
    driver = next((p for p in ("/usr/bin/chromedriver", shutil.which("chromedriver")) if p and Path(p).is_file()), None)
    if not chromium:
        unavailable("chromium is not installed")
    if not driver:
        unavailable("chromedriver is not installed")
    return chromium, driver


def srgb8(linear):
    x = np.asarray(linear, np.float64)
    s = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(np.maximum(x, 0.0031308), 1 / 2.4) - 0.055)
    return (np.clip(s, 0, 1) * 255 + 0.5).astype(np.uint8)


def make_photo(path):
    """Sample 1 of the nets card's chunk (a torus), sRGB, 8-bit, scaled up to 128 x 128."""
    from PIL import Image

    with tarfile.open(SAMPLES) as tar:
        member = tar.getmember("00000001.image.npy")
        image = np.load(io.BytesIO(tar.extractfile(member).read()))
    Image.fromarray(srgb8(image[..., :3])).resize((128, 128), Image.BILINEAR).save(path)


class Server:
    """`matedit serve --port 0 --steps 4`; its URL from the first stderr line, the rest kept.
    Four refinement steps, not the default 20: these tests are of the page, and the steps are
    most of what a debug build spends on a photo (the refinement's quality is tested in Rust)."""

    def __init__(self, binary, cwd):
        self.lines = []
        self.proc = subprocess.Popen([str(binary), "serve", "--port", "0", "--steps", "4"], cwd=cwd,
                                     stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                                     stderr=subprocess.PIPE, text=True, errors="replace")
        self.url = None
        found = threading.Event()

        def pump():  # keep reading so the server never blocks on a full pipe
            for line in self.proc.stderr:
                self.lines.append(line.rstrip())
                m = re.search(r"serving (http://\S+?)/?$", line.strip())
                if m and not found.is_set():
                    self.url = m.group(1)
                    found.set()
            found.set()

        threading.Thread(target=pump, daemon=True).start()
        found.wait(60)
        if not self.url:
            self.stop()
            pytest.fail("matedit serve did not say where it serves:\n" + self.log())

    def log(self, n=40):
        return "\n".join(self.lines[-n:])

    def get(self, path):
        with urllib.request.urlopen(self.url + path, timeout=60) as r:
            return r.read()

    def post_json(self, path, body):
        req = urllib.request.Request(self.url + path, data=body.encode(), method="POST",
                                     headers={"Content-Type": "application/json"})
        with urllib.request.urlopen(req, timeout=120) as r:
            assert r.headers.get("Content-Type", "").startswith("image/png")
            return r.read()

    def stop(self):
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()


def decode(data):
    from PIL import Image

    return np.asarray(Image.open(io.BytesIO(data)).convert("RGB")).astype(np.int16)


# the displayed <img>'s pixels: drawn to a canvas, RGBA as base64
READ_PIXELS = """
const img = arguments[0], c = document.createElement('canvas');
c.width = img.naturalWidth; c.height = img.naturalHeight;
const g = c.getContext('2d'); g.drawImage(img, 0, 0);
const d = g.getImageData(0, 0, c.width, c.height).data;
let s = '';
for (let i = 0; i < d.length; i += 0x8000) s += String.fromCharCode.apply(null, d.subarray(i, i + 0x8000));
return [c.width, c.height, btoa(s)];
"""


def displayed(driver, element):
    w, h, b64 = driver.execute_script(READ_PIXELS, element)
    return np.frombuffer(base64.b64decode(b64), np.uint8).reshape(h, w, 4)[..., :3].astype(np.int16)


def test_page_in_a_browser(tmp_path):
    binary = find_binary()
    chromium, chromedriver = find_browser()
    try:
        from selenium import webdriver
        from selenium.webdriver.chrome.service import Service
        from selenium.webdriver.common.by import By
    except ImportError:
        unavailable("selenium is not installed (pip install selenium)")
    try:
        import PIL  # noqa: F401
    except ImportError:
        unavailable("Pillow is not installed")

    photo = tmp_path / "photo.png"
    make_photo(photo)
    server = Server(binary, tmp_path)
    opts = webdriver.ChromeOptions()
    opts.binary_location = chromium
    for arg in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                "--window-size=1280,900"):
        opts.add_argument(arg)
    opts.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    driver = None
    try:
        driver = webdriver.Chrome(service=Service(chromedriver), options=opts)
        js = driver.execute_script

        def browser_log():
            return "\n".join(f"{e.get('level')}: {e.get('message')}" for e in driver.get_log("browser"))

        def wait_for(what, cond, timeout):
            end = time.monotonic() + timeout
            while time.monotonic() < end:
                v = cond()
                if v:
                    return v
                time.sleep(0.1)
            pytest.fail(f"timed out after {timeout} s waiting for {what}; page: "
                        + json.dumps(js("return {state: document.body.dataset.state,"
                                        " status: document.getElementById('status').textContent,"
                                        " error: document.getElementById('error').textContent,"
                                        " edit: document.getElementById('edit').dataset}"))
                        + "\nbrowser log:\n" + browser_log() + "\nserver log:\n" + server.log())

        def full_edit(check):
            """Waits for #edit's data-state "done" with a request that passes check."""
            def done():
                d = js("const e = document.getElementById('edit');"
                       " return [e.dataset.state, e.dataset.request || '', e.complete && e.naturalWidth]")
                return d[0] == "done" and d[2] and check(json.loads(d[1])) and d[1]
            return wait_for("a full edit", done, EDIT_TIMEOUT)

        driver.get(server.url + "/")
        wait_for("the preset gallery", lambda: js("return document.querySelectorAll('#gallery .preset').length"), 30)

        # upload, analyse as it is (no box, no point) and decompose
        driver.find_element(By.ID, "file").send_keys(str(photo))
        wait_for("the photo to point at", lambda: js("return document.body.dataset.state") == "pointing", 30)
        driver.find_element(By.ID, "analyse").click()
        wait_for("the decomposition",
                 lambda: js("return document.body.dataset.state") in ("ready", "failed"), READY_TIMEOUT)
        assert js("return document.body.dataset.state") == "ready", (
            js("return document.getElementById('error').textContent") + "\nbrowser log:\n" + browser_log()
            + "\nserver log:\n" + server.log())
        assert not driver.find_element(By.ID, "error").is_displayed()
        imgs = "Array.from(document.querySelectorAll('#decomp img, #before'))"
        wait_for("the decomposition's pictures",
                 lambda: js(f"return {imgs}.every(i => i.complete)"), 30)
        sizes = js(f"return {imgs}.map(i => [i.id, i.naturalWidth])")
        assert all(w > 0 for _, w in sizes), sizes
        photo_id = js("return document.body.dataset.photo")
        assert re.fullmatch(r"[0-9a-f]+", photo_id), photo_id

        # a preset: the full edit shown is the server's answer to the same request
        preset = PRESET if js(f"return !!document.querySelector('.preset[data-preset=\"{PRESET}\"]')") \
            else js("return document.querySelector('.preset').dataset.preset")
        button = driver.find_element(By.CSS_SELECTOR, f'.preset[data-preset="{preset}"]')
        js("arguments[0].scrollIntoView({block: 'nearest'})", button)
        button.click()
        request = full_edit(lambda r: r.get("material") == preset and r.get("preview") is False)
        assert "selected" in button.get_attribute("class")
        shown = displayed(driver, driver.find_element(By.ID, "edit"))
        served = decode(server.post_json(f"/api/photos/{photo_id}/edit", request))
        assert shown.shape == served.shape, (shown.shape, served.shape)
        assert np.abs(shown - served).max() <= 2
        original = decode(server.get(f"/api/photos/{photo_id}/photo.png"))
        mask = decode(server.get(f"/api/photos/{photo_id}/mask.png"))[..., 0] > 127
        assert original.shape == shown.shape and mask.shape == shown.shape[:2], (original.shape, mask.shape)
        assert 16 <= mask.sum() < mask.size
        diff = np.abs(shown - original).max(-1)
        assert diff[mask].mean() > 3, f"the object hardly changed: {diff[mask].mean():.2f}"
        near = mask.copy()  # the mask grown by 3 pixels: the soft edge of the composite
        for _ in range(3):
            grown = near.copy()
            grown[1:] |= near[:-1]
            grown[:-1] |= near[1:]
            grown[:, 1:] |= near[:, :-1]
            grown[:, :-1] |= near[:, 1:]
            near = grown
        background = ~near
        assert background.sum() > 0.1 * mask.size
        kept = (diff[background] <= 2).mean()
        assert kept >= 0.9, f"only {kept:.1%} of the background is the photo's"
        assert js("return document.getElementById('download-edit').href").startswith("blob:")
        assert f"/api/presets/{preset}/material.json" in js("return document.getElementById('download-material').href")

        shot = Path(os.environ.get("MATEDIT_SCREENSHOT") or tmp_path / "page.png")
        shot.parent.mkdir(parents=True, exist_ok=True)
        driver.save_screenshot(str(shot))

        # the turn slider: previews while moving, then a new full edit on release
        js("const t = document.getElementById('turn'); t.value = 90;"
           " t.dispatchEvent(new Event('input', {bubbles: true}));"
           " t.dispatchEvent(new Event('change', {bubbles: true}));")
        full_edit(lambda r: r.get("turn") == 90 and r.get("material") == preset and r.get("preview") is False)
        turned = displayed(driver, driver.find_element(By.ID, "edit"))
        assert turned.shape == shown.shape
        assert np.abs(turned - shown).max(-1)[mask].mean() > 2, "turning the light changed nothing"

        # "material from another photo": a second upload, its material selected when ready
        driver.find_element(By.ID, "like-file").send_keys(str(photo))
        like = json.loads(full_edit(lambda r: "like" in r and "material" not in r))["like"]
        assert like != photo_id
        assert js("return document.getElementById('swatch').src").endswith(f"/api/photos/{like}/sphere.png")
        assert js("return document.getElementById('download-material').href").endswith(f"/api/photos/{like}/material.json")
        assert not js("return document.querySelector('.preset.selected')")

        # an error: a "PNG" that is text
        bad = tmp_path / "not-a-photo.png"
        bad.write_text("this is not an image\n")
        driver.find_element(By.ID, "file").send_keys(str(bad))
        wait_for("the error", lambda: js("return document.body.dataset.state") == "failed", 30)
        error = driver.find_element(By.ID, "error")
        assert error.is_displayed() and error.text.strip(), error.text
        assert js("return document.getElementById('file').disabled") is False

        # the page closed the photo's event stream after "ready" (no reconnections)
        assert sum(f"/api/photos/{photo_id}/events" in line for line in server.lines) <= 1, server.log()
        # no script errors on the page
        logs = [e["message"] for e in driver.get_log("browser") if e.get("level") == "SEVERE"]
        assert not [m for m in logs if "Uncaught" in m or "TypeError" in m], logs
    finally:
        if driver is not None:
            driver.quit()
        server.stop()


def make_two(path):
    """Two of make_photo's tori side by side (256 x 128): the nets find no single object."""
    from PIL import Image

    one = path.with_name("one.png")
    make_photo(one)
    t = np.asarray(Image.open(one).convert("RGB"))
    Image.fromarray(np.concatenate([t, t], 1)).save(path)


# the pointing canvas's pixels, RGBA as base64
READ_CANVAS = """
const c = arguments[0], d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
let s = '';
for (let i = 0; i < d.length; i += 0x8000) s += String.fromCharCode.apply(null, d.subarray(i, i + 0x8000));
return [c.width, c.height, btoa(s)];
"""


def test_pointing_in_a_browser(tmp_path):
    binary = find_binary()
    chromium, chromedriver = find_browser()
    try:
        from selenium import webdriver
        from selenium.webdriver.chrome.service import Service
        from selenium.webdriver.common.action_chains import ActionChains
        from selenium.webdriver.common.by import By
        from selenium.webdriver.common.keys import Keys
    except ImportError:
        unavailable("selenium is not installed (pip install selenium)")
    try:
        import PIL  # noqa: F401
    except ImportError:
        unavailable("Pillow is not installed")

    photo = tmp_path / "two.png"
    make_two(photo)
    server = Server(binary, tmp_path)
    opts = webdriver.ChromeOptions()
    opts.binary_location = chromium
    for arg in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                "--window-size=1280,900", "--force-device-scale-factor=1"):
        opts.add_argument(arg)
    opts.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    driver = None
    try:
        driver = webdriver.Chrome(service=Service(chromedriver), options=opts)
        js = driver.execute_script

        def wait_for(what, cond, timeout):
            end = time.monotonic() + timeout
            while time.monotonic() < end:
                v = cond()
                if v:
                    return v
                time.sleep(0.1)
            pytest.fail(f"timed out after {timeout} s waiting for {what}; page: "
                        + json.dumps(js("return {state: document.body.dataset.state,"
                                        " status: document.getElementById('status').textContent,"
                                        " error: document.getElementById('error').textContent,"
                                        " mask: document.getElementById('point-stage').dataset}"))
                        + "\nserver log:\n" + server.log())

        state = lambda: js("return document.body.dataset.state")  # noqa: E731
        driver.get(server.url + "/")
        wait_for("the preset gallery", lambda: js("return document.querySelectorAll('#gallery .preset').length"), 30)
        driver.find_element(By.ID, "file").send_keys(str(photo))
        wait_for("the photo to point at", lambda: state() == "pointing", 30)
        canvas = driver.find_element(By.ID, "point-canvas")
        wait_for("the photo", lambda: js("const i = document.getElementById('point-photo');"
                                         " return i.complete && i.naturalWidth"), READY_TIMEOUT)

        # as it is: the nets find two objects and the refusal asks for a box
        driver.find_element(By.ID, "analyse").click()
        error = driver.find_element(By.ID, "error")
        wait_for("the refusal", lambda: error.is_displayed() and state() == "pointing", READY_TIMEOUT)
        assert "no single object found" in error.text and "drag a box" in error.text, error.text
        assert not driver.find_element(By.ID, "editor").is_displayed()

        # a box dragged around the left torus: its mask drawn over the photo
        w, h = canvas.size["width"], canvas.size["height"]
        k = w / 256  # page pixels per photo pixel

        def at(x, y):  # a photo pixel as an offset from the canvas's centre
            return round((x + 0.5) * k - w / 2), round((y + 0.5) * k - h / 2)

        ActionChains(driver).move_to_element_with_offset(canvas, *at(3, 3)).click_and_hold() \
            .move_to_element_with_offset(canvas, *at(60, 60)) \
            .move_to_element_with_offset(canvas, *at(124, 124)).release().perform()
        stage = driver.find_element(By.ID, "point-stage")
        wait_for("the mask", lambda: stage.get_attribute("data-mask") == "shown", EDIT_TIMEOUT)
        assert not error.is_displayed(), error.text
        first = int(stage.get_attribute("data-pixels"))
        cw, ch, b64 = js(READ_CANVAS, canvas)
        overlay = np.frombuffer(base64.b64decode(b64), np.uint8).reshape(ch, cw, 4)
        tinted = (overlay[..., 3] > 0) & (overlay[..., 2] > 200)   # the mask's blue, half opaque
        half = cw // 2
        assert tinted[:, :half].mean() > 0.2, tinted[:, :half].mean()
        assert tinted[:, half:].mean() < 0.01, tinted[:, half:].mean()
        # a shift-click in the torus's hole: not the object, a new mask; undo takes it back
        ActionChains(driver).move_to_element_with_offset(canvas, *at(64, 64)).key_down(Keys.SHIFT).click() \
            .key_up(Keys.SHIFT).perform()
        info = driver.find_element(By.ID, "point-info")
        wait_for("the point", lambda: "1 off" in info.text, 5)
        wait_for("the refined mask", lambda: stage.get_attribute("data-mask") == "shown", EDIT_TIMEOUT)
        shot = Path(os.environ.get("MATEDIT_POINTING_SCREENSHOT") or tmp_path / "pointing.png")
        shot.parent.mkdir(parents=True, exist_ok=True)
        driver.save_screenshot(str(shot))
        driver.find_element(By.ID, "point-undo").click()
        wait_for("the undone point", lambda: "0 off" in info.text, 5)
        wait_for("the mask again", lambda: stage.get_attribute("data-mask") == "shown"
                 and int(stage.get_attribute("data-pixels")) == first, EDIT_TIMEOUT)
        # a plain click on the torus: a point on the object
        ActionChains(driver).move_to_element_with_offset(canvas, *at(64, 12)).click().perform()
        wait_for("the point on it", lambda: "1 on" in info.text, 5)
        wait_for("its mask", lambda: stage.get_attribute("data-mask") == "shown", EDIT_TIMEOUT)

        # analysed with the box, then edited
        driver.find_element(By.ID, "analyse").click()
        wait_for("the decomposition", lambda: state() in ("ready", "failed") or
                 (state() == "pointing" and error.is_displayed()), READY_TIMEOUT)
        assert state() == "ready", error.text + "\n" + server.log()
        photo_id = js("return document.body.dataset.photo")
        mask = decode(server.get(f"/api/photos/{photo_id}/mask.png"))[..., 0] > 127
        assert mask[:, :128].sum() > 1000 and mask[:, 128:].sum() == 0, (mask[:, :128].sum(), mask[:, 128:].sum())
        button = driver.find_element(By.CSS_SELECTOR, ".preset")
        js("arguments[0].scrollIntoView({block: 'nearest'})", button)
        button.click()
        wait_for("the edit", lambda: js("const e = document.getElementById('edit');"
                                        " return e.dataset.state === 'done' && e.complete && e.naturalWidth"),
                 EDIT_TIMEOUT)
        assert driver.find_element(By.ID, "edit").is_displayed()
        logs = [e["message"] for e in driver.get_log("browser") if e.get("level") == "SEVERE"]
        assert not [m for m in logs if "Uncaught" in m or "TypeError" in m], logs
    finally:
        if driver is not None:
            driver.quit()
        server.stop()
