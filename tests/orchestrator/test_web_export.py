"""`rig export web` in a real browser: headless Chromium (Debian's, driven by Selenium)
loads the site from file://, with no console error; at the starting camera and light
the page's BTF matches `rig view`'s render of the same material; dragging the light
changes the image; the catalogue's links open the pages. `make tools` installs
Chromium, its driver and Selenium; without them these tests skip, saying so."""

import base64
import io
import json
import shutil
import time
from pathlib import Path

import numpy as np
import pytest
from PIL import Image
from typer.testing import CliRunner

from orchestrator.cli import app
from orchestrator.web_site import CAMERA, CANVAS, LIGHT
from tests.rig.material.conftest import make_archive, pbr_maps, pca_model

# Simulated sessions, rendered targets or fits of seconds each: make test only, not make quick.
pytestmark = pytest.mark.slow

runner = CliRunner()
CHROMIUM, DRIVER = shutil.which("chromium"), shutil.which("chromedriver")
#: the BTF image may differ from `rig view`'s by this much, in 8-bit sRGB codes (measured:
#: mean 0.3, 99th percentile 1 on the demo weave; the rest is the outline's rasterisation)
MEAN_CODES, P99_CODES = 1.0, 4.0


@pytest.fixture
def browser():
    """A headless Chromium per test (the leak check wants its processes gone after each)."""
    webdriver = pytest.importorskip("selenium.webdriver", reason="selenium: `make tools`")
    if CHROMIUM is None or DRIVER is None:
        pytest.skip("no chromium/chromedriver: `make tools` (Debian's chromium, chromium-driver)")
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    options.binary_location = CHROMIUM
    for argument in ("--headless=new", "--no-sandbox", "--use-angle=swiftshader",
                     "--enable-unsafe-swiftshader", "--window-size=900,800"):  # fmt: skip
        options.add_argument(argument)
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    driver = webdriver.Chrome(service=Service(DRIVER), options=options)
    yield driver
    driver.quit()


@pytest.fixture(scope="module")
def site(tmp_path_factory):
    folder = tmp_path_factory.mktemp("web")
    archive = make_archive(folder / "weave.zarr", btf=pca_model(), pbr=pbr_maps(n=8))
    out = folder / "site"
    result = runner.invoke(app, ["export", "web", str(archive), "--out", str(out)])
    assert result.exit_code == 0, result.output
    return archive, out


def _open(browser, page: Path):
    browser.get(page.as_uri())
    deadline = time.monotonic() + 60
    while browser.execute_script("return document.body.dataset.ready") != "1":
        assert time.monotonic() < deadline, "the viewer never reported ready"
        time.sleep(0.2)


def _canvas(browser) -> np.ndarray:
    url = browser.execute_script("return document.getElementById('view').toDataURL('image/png')")
    return np.asarray(Image.open(io.BytesIO(base64.b64decode(url.split(",")[1]))).convert("RGB"))


def _errors(browser) -> list:
    return [e for e in browser.get_log("browser") if e["level"] in ("SEVERE", "ERROR")]


def test_the_btf_page_matches_rig_view(browser, site, tmp_path):
    archive, out = site
    _open(browser, out / "weave" / "index.html")
    page = _canvas(browser).astype(np.int16)
    assert _errors(browser) == []
    exposure = browser.execute_script("return window.btfrigViewer.state.exposure")
    png = tmp_path / "view.png"
    args = ["view", str(archive), "--mesh", "plane", "--no-mdf", "--camera", CAMERA,
            "--light", LIGHT, "--size", f"{CANVAS[0]}x{CANVAS[1]}", "--exposure", str(exposure),
            "--out", str(png)]  # fmt: skip
    result = runner.invoke(app, args)
    assert result.exit_code == 0, result.output
    reference = np.asarray(Image.open(png).convert("RGB")).astype(np.int16)
    difference = np.abs(page - reference)
    assert reference.mean() > 5  # something lit to compare
    assert difference.mean() <= MEAN_CODES
    assert np.percentile(difference, 99) <= P99_CODES


def test_dragging_the_light_and_the_pbr_toggle_change_the_image(browser, site):
    from selenium.webdriver.common.action_chains import ActionChains
    from selenium.webdriver.common.keys import Keys

    _, out = site
    _open(browser, out / "weave" / "index.html")
    before = _canvas(browser).astype(np.int16)
    canvas = browser.find_element("id", "view")
    chain = ActionChains(browser).key_down(Keys.SHIFT).click_and_hold(canvas)
    chain.move_by_offset(120, 40).release().key_up(Keys.SHIFT).perform()
    light = browser.execute_script("return window.btfrigViewer.state.light")
    assert light != [40, -130]
    after = _canvas(browser).astype(np.int16)
    assert np.abs(after - before).mean() > 1.0
    browser.find_element("id", "mode").click()
    fitted = _canvas(browser).astype(np.int16)
    assert fitted.mean() > 1.0 and np.abs(fitted - after).mean() > 0.5
    assert _errors(browser) == []


def test_the_catalogue_links_open_the_pages(browser, site):
    _, out = site
    manifest = json.loads((out / "manifest.json").read_text())
    browser.get((out / "index.html").as_uri())
    links = browser.find_elements("css selector", "a")
    targets = {link.get_attribute("href") for link in links}
    assert (out / "weave" / "index.html").as_uri() in targets
    assert "PBR fit error" in browser.page_source
    links[1].click()
    deadline = time.monotonic() + 60
    while browser.execute_script("return document.body.dataset.ready") != "1":
        assert time.monotonic() < deadline
        time.sleep(0.2)
    assert browser.current_url.endswith("weave/index.html")
    assert manifest["materials"][0]["page"] == "weave/index.html"
    assert _errors(browser) == []


def test_pictures_of_an_exported_site(browser):
    """With BTFRIG_WEB_SITE=SITE (a `rig export web` folder) and BTFRIG_WEB_PICTURES=STEM:
    the first page of SITE on the cloth as the README shows it (STEM.png) and its BTF, PBR
    fit and 4 × their difference side by side (STEM_fit.png), for docs/interchange.md."""
    import os

    site, stem = os.environ.get("BTFRIG_WEB_SITE"), os.environ.get("BTFRIG_WEB_PICTURES")
    if not site or not stem:
        pytest.skip("set BTFRIG_WEB_SITE and BTFRIG_WEB_PICTURES to take the docs' pictures")
    first = json.loads((Path(site) / "manifest.json").read_text())["materials"][0]["page"]
    _open(browser, Path(site).resolve() / first)
    browser.execute_script("window.btfrigViewer.setMesh('cloth'); window.btfrigViewer.draw()")
    browser.save_screenshot(f"{stem}.png")
    btf = _canvas(browser).astype(np.int16)
    browser.find_element("id", "mode").click()
    fit = _canvas(browser).astype(np.int16)
    difference = np.clip(4 * np.abs(btf - fit), 0, 255)
    strip = np.concatenate([btf, fit, difference], axis=1).astype(np.uint8)
    half = (strip.shape[1] // 2, strip.shape[0] // 2)
    Image.fromarray(strip).resize(half).save(f"{stem}_fit.png")
    assert _errors(browser) == []
