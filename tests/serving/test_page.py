"""The page in a real browser: Debian's headless Chromium driven by Selenium (nothing is downloaded).

Types a response, checks that the grounding, the tendon curves and the trunk's motion appear, that a held text
shows "holding still: <reason>" with no tuple in large type (only the nearest one, in small print), turns the live
stream on, and saves a screenshot to docs/serving/page.png. Chromium and its driver are installed by
scripts/install_system.sh (run by ``make install``); in CI (``CI=true``) their absence fails the test.
"""

from __future__ import annotations

import os
import time
from pathlib import Path

import pytest
from browser import headless_chromium, wait_for

SCREENSHOT = Path(__file__).resolve().parents[2] / "docs" / "serving" / "page.png"


@pytest.fixture(scope="module")
def browser():
    yield from headless_chromium()


def test_page_grounds_a_response_and_moves_the_trunk(browser, running):
    from selenium.webdriver.common.by import By
    from selenium.webdriver.common.keys import Keys

    from jgrounding import vocabulary

    browser.get(running.http)
    wait_for(browser, "return document.body.dataset.ready === '1'")
    box = browser.find_element(By.ID, "text")
    box.clear()
    box.send_keys("Wave hello to our new visitor!", Keys.ENTER)
    intent = wait_for(browser, "const t = document.getElementById('intent').textContent; return t !== '-' && t")
    assert intent.replace(" ", "_") in vocabulary.INTENTS
    assert browser.find_element(By.ID, "intensity").text in vocabulary.INTENSITIES
    assert browser.find_element(By.ID, "confidence").text.endswith("%")
    assert browser.find_element(By.ID, "status").text.startswith(("Acting", "holding still: "))
    curves = browser.execute_script(  # the SVG is redrawn every frame: read it in one go
        "return [...document.querySelectorAll('#tendons polyline.tendon')].map(p => p.dataset.points)"
    )
    assert curves == ["150"] * 4
    first = int(
        wait_for(
            browser,
            "return Number(document.getElementById('trunk').dataset.frames) > 5 && "
            "document.getElementById('trunk').dataset.frame",
        )
    )
    time.sleep(0.7)
    assert int(browser.find_element(By.ID, "trunk").get_attribute("data-frame")) != first  # the trunk moves
    drawn = browser.execute_script(  # pixels of the trunk's colour on the canvas
        "const c = document.getElementById('trunk'), d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;"
        "let n = 0; for (let i = 0; i < d.length; i += 4) if (d[i] === 0x6c && d[i+1] === 0x58 && d[i+2] === 0x4c) n++;"
        "return n;"
    )
    assert drawn > 200
    SCREENSHOT.parent.mkdir(parents=True, exist_ok=True)
    tmp = SCREENSHOT.with_suffix(".tmp.png")
    browser.save_screenshot(str(tmp))
    os.replace(tmp, SCREENSHOT)

    box.clear()  # a held text: the reason first, no tuple in large type, the nearest one in small print
    box.send_keys("please stay still, the nurse is checking you", Keys.ENTER)
    status = wait_for(
        browser, "const t = document.getElementById('status').textContent; return t.startsWith('holding') && t"
    )
    assert status.startswith("holding still: the text orders the trunk to keep still")
    assert browser.find_element(By.ID, "intent").text == "-" and browser.find_element(By.ID, "intensity").text == "-"
    assert browser.find_element(By.ID, "nearest").text.startswith("nearest: (")
    held = SCREENSHOT.with_name("page_hold.png")  # the held state, for docs/acting.md
    browser.save_screenshot(str(held.with_suffix(".tmp.png")))
    os.replace(held.with_suffix(".tmp.png"), held)
    box.clear()
    box.send_keys("Wave hello to our new visitor!", Keys.ENTER)
    wait_for(browser, "return document.getElementById('status').textContent.startsWith('Acting')")

    browser.find_element(By.ID, "stream").click()  # the live stream
    wait_for(browser, "return /tick [4-9][0-9]/.test(document.getElementById('streaminfo').textContent)")
    assert "streaming" in browser.find_element(By.ID, "streaminfo").text
    browser.find_element(By.ID, "stream").click()
    wait_for(browser, "return document.getElementById('streaminfo').textContent.startsWith('stream ended')")
    assert browser.find_element(By.ID, "error").text == ""
