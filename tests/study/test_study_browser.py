"""Whole studies through the real server, database and pages: simulated participants (ratings drawn from known
distributions, one of them dropping out) answer on the participant's page in headless Chromium while the
operator's page enrols them and plays the episodes: AV-only and the trunk moved by the model through the live
stream. Chromium options as in tests/serving/test_page.py."""

from __future__ import annotations

import dataclasses
import time

import numpy as np
import pytest
from browser import headless_chromium, wait_for

SQLALCHEMY = pytest.importorskip(
    "sqlalchemy", reason="the study's database needs sqlalchemy (requirements.txt pins it)"
)
from jgrounding.study import Design, Episode, Store  # noqa: E402 (after the skip: the store imports sqlalchemy)

pytestmark = pytest.mark.slow  # the model, Chromium and five 5 s episodes: about 60 s on 2 cores


@pytest.fixture(scope="module")
def browser():
    yield from headless_chromium(
        (
            "--disable-background-timer-throttling",
            "--disable-renderer-backgrounding",
        )
    )


def test_simulated_participants_run_a_study_through_the_pages(browser, tmp_path):
    from selenium.webdriver.common.by import By

    from jgrounding import serving
    from jgrounding.study import simulate
    from jgrounding.study.__main__ import analyze
    from jgrounding.study.app import StudyServer

    design = Design(
        name="browser",
        episodes=(Episode("Hello! Nice to meet you.", intent="greeting", intensity="pronounced"),),
        stall_s=5.0,
    )
    store = Store(tmp_path / "study.db")
    run = serving.Running(StudyServer(design, store, serving.Policy()))
    model = dataclasses.replace(simulate.paper_model(), dropout=0.0)
    people = [simulate.SimulatedParticipant(model, np.random.default_rng(k)) for k in range(3)]
    given: dict = {}
    try:
        browser.get(run.http + "study/operator")
        operator = browser.current_window_handle
        wait_for(browser, "return document.body.dataset.ready === '1'")
        for k, person in enumerate(people):
            browser.switch_to.window(operator)
            before = browser.find_element(By.ID, "pid").text
            browser.find_element(By.ID, "enrol").click()
            pid = wait_for(
                browser, f"const t = document.getElementById('pid').textContent; return t !== '{before}' && t"
            )
            wait_for(browser, f"return document.getElementById('plink').textContent.endsWith('{pid}')")
            link = browser.find_element(By.ID, "plink").get_attribute("href")
            browser.switch_to.new_window("tab")
            browser.get(link)
            participant = browser.current_window_handle
            wait_for(browser, "return document.body.dataset.ready === '1'")
            order = store.participant(pid)["order"]
            for position, condition in enumerate(order):
                if k == 2 and position == 1:  # the third participant leaves after the first block
                    break
                browser.switch_to.window(operator)
                wait_for(  # the page shows this block's condition and lets the operator play its episode
                    browser,
                    f"return !document.getElementById('play').disabled && "
                    f"document.getElementById('condition').textContent === '{condition}'",
                )
                browser.find_element(By.ID, "play").click()
                wait_for(browser, "return document.getElementById('phase').dataset.phase === 'questionnaire'")
                browser.switch_to.window(participant)
                wait_for(
                    browser,
                    f"return document.body.dataset.phase === 'questionnaire' && document.body.dataset.position === '{position}'",
                )
                answers = person.rate(condition, position)
                for dim, value in answers.items():
                    browser.find_element(By.ID, f"q-{dim}-{value}").click()
                    time.sleep(0.05)
                given[(pid, position)] = answers
                wait_for(browser, "return document.body.dataset.phase !== 'questionnaire'")
            browser.switch_to.window(operator)
            if k == 2:
                browser.find_element(By.ID, "withdraw").click()
                wait_for(browser, "return document.getElementById('phase').dataset.phase === 'withdrawn'")
            browser.switch_to.window(participant)
            wait_for(browser, "return ['done', 'withdrawn'].includes(document.body.dataset.phase)")
            browser.close()
        browser.switch_to.window(operator)
        drawn = browser.execute_script(
            "const c = document.getElementById('trunk'), d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;"
            "let n = 0; for (let i = 0; i < d.length; i += 4) if (d[i] === 0x6c && d[i+1] === 0x58 && d[i+2] === 0x4c) n++;"
            "return n;"
        )
        assert drawn > 200  # the simulated trunk from the stream's backbone
        browser.save_screenshot(str(tmp_path / "operator.png"))
        assert browser.find_element(By.ID, "error").text == ""
    finally:
        run.stop()

    rows = store.long_ratings()
    got = {(r["participant_id"], r["position"], r["dimension"]): r["value"] for r in rows}
    assert got == {(p, pos, d): v for (p, pos), answers in given.items() for d, v in answers.items()}
    parts = store.participants(store.sessions()[0]["id"])
    assert [p["order"] for p in parts] == [["av_only", "trunk"], ["trunk", "av_only"], ["av_only", "trunk"]]
    assert [p["status"] for p in parts] == ["complete", "complete", "withdrawn"]
    runs = store.table("executions")
    assert len(runs) == 5 and all(e["planned_sha256"] == e["executed_sha256"] for e in runs)
    assert {e["source"] for e in runs if e["condition"] == "trunk"} == {"model"}
    assert len({e["seed"] for e in runs}) == 5
    report = analyze(tmp_path / "study.db", tmp_path / "analysis")
    assert report["participants"] == 3 and (tmp_path / "analysis" / "positive_ratio.png").exists()
    assert report["comparisons"][0]["tests"][0]["pairs"] == 2  # the dropout has no pair
