"""The explore page in a real headless browser: Debian's Chromium driven by Playwright (its own
browser download is never used). Points drawn, a selection, the filters, export, repetitions,
and the on-demand rollout with the native engine standing in for the compiled one.

Without Chromium or Playwright the tests are skipped here, and fail under CI (CI=true), where
``.ci/run`` installs both."""

from mjxskill.evaluation.render import default_gl

default_gl()

import os  # noqa: E402
import shutil  # noqa: E402

import numpy as np  # noqa: E402
import pytest  # noqa: E402

from explore_runs import make_push_run, make_repeated_run  # noqa: E402
from explore_server import NativeStandIn, select_export, serving  # noqa: E402
from mjxskill.explore.solutions import Solutions  # noqa: E402
from capabilities import no_render  # noqa: E402

CHROMIUM = os.environ.get("MJXSKILL_CHROMIUM", "/usr/bin/chromium")
FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run", "--disable-background-networking",
         "--disable-component-update", "--disable-sync"]


def _unavailable(reason: str):
    if os.environ.get("CI"):
        pytest.fail(f"{reason} (.ci/run installs it)")
    pytest.skip(reason)


@pytest.fixture(scope="module")
def browser():
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        _unavailable("Playwright for Python is not installed (pip install -e '.[test]')")
    if shutil.which(CHROMIUM) is None:
        _unavailable(f"no Chromium at {CHROMIUM} (apt-get install chromium)")
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=shutil.which(CHROMIUM), args=FLAGS)
        yield browser
        browser.close()


@pytest.fixture
def open_page(browser):
    """open_page(base_url) -> a page with the run drawn; fails the test on a script error."""
    pages, errors = [], []

    def open_(base):
        page = browser.new_page(viewport={"width": 1400, "height": 1000})
        page.on("pageerror", lambda err: errors.append(str(err)))
        page.goto(base + "/")
        page.wait_for_selector("body[data-ready=true]", timeout=30_000)
        pages.append(page)
        return page

    yield open_
    for page in pages:
        page.close()
    assert errors == []


def test_every_pareto_row_is_drawn_and_every_evaluation(tmp_path, open_page):
    run = make_push_run(tmp_path / "push-0")
    with serving(run.path) as base:
        page = open_page(base)
        assert page.locator("#pareto circle.front").count() == len(run.pareto())
        assert page.locator("#pareto circle.evaluation").count() == len(run.evaluations())
        assert page.locator("#front-table tr[data-k]").count() == len(run.pareto())
        assert page.locator("#hypervolume path.hv-line").count() == 1


def test_selecting_a_point_shows_its_parameters_with_units(tmp_path, open_page):
    run = make_push_run(tmp_path / "push-0")
    config, front = run.config(), run.pareto()
    with serving(run.path) as base:
        page = open_page(base)
        page.locator('#pareto circle.front[data-k="2"]').click()
        assert page.locator("#detail-title").inner_text() == "Pareto solution k = 2"
        rows = page.locator("#params tr[data-name]")
        assert rows.count() == len(config.parameter_names)
        for i, (name, unit) in enumerate(zip(config.parameter_names, config.parameter_units)):
            cells = rows.nth(i).locator("td").all_inner_texts()
            assert cells[0] == name and cells[2] == unit
            assert float(cells[1]) == pytest.approx(front.params[2, i], rel=1e-5)
        text = page.locator("#objectives").inner_text()
        assert f"{round(100 * front.success_rate[2])} %" in text and f"{front.peak_contact_force[2]:.1f} N" in text


def test_filters_highlight_the_solutions_meeting_them(tmp_path, open_page):
    run = make_push_run(tmp_path / "push-0")
    front = run.pareto()
    with serving(run.path) as base:
        page = open_page(base)
        assert page.locator("#pareto circle.front.meets").count() == 0
        page.fill("#min-success", "0.5")
        page.fill("#max-force", "20")
        meets = (front.success_rate >= 0.5) & (front.peak_contact_force <= 20)
        assert 0 < meets.sum() < len(front)
        drawn = sorted(int(k) for k in page.locator("#pareto circle.front.meets").evaluate_all("cs => cs.map(c => c.dataset.k)"))
        assert drawn == np.flatnonzero(meets).tolist()
        assert page.locator("#pareto circle.front.fails").count() == len(front) - meets.sum()
        assert page.locator("#filter-count").inner_text() == f"{meets.sum()} of {len(front)} Pareto solutions meet the filters"
        page.click("#pick-best")
        from mjxskill.evaluation.selection import choose

        page.wait_for_selector(f'#front-table tr.selected[data-k="{choose(front, 20, 0.5)}"]')


def test_export_writes_the_files_select_writes(tmp_path, open_page):
    run = make_push_run(tmp_path / "push-0")
    with serving(run.path) as base:
        page = open_page(base)
        page.locator('#pareto circle.front[data-k="3"]').click()
        page.click("#export")
        page.wait_for_function("document.getElementById('export-result').textContent.startsWith('wrote')")
    exported = {p.name: p.read_bytes() for p in sorted((run.path / "selected-3").iterdir())}
    assert exported == select_export(run.path, 3, tmp_path / "by-select")


def test_repetitions_have_one_colour_each(tmp_path, open_page):
    root = make_repeated_run(tmp_path / "push-x3", repeats=3)
    with serving(root.path) as base:
        page = open_page(base)
        fronts = [len((root.path / f"seed-{s}").joinpath("pareto.csv").read_text().splitlines()) - 1 for s in range(3)]
        assert page.locator("#pareto circle.front").count() == sum(fronts)
        colours = page.locator("#pareto circle.front").evaluate_all("cs => cs.map(c => [c.dataset.run, c.getAttribute('fill')])")
        by_run = {}
        for run, fill in colours:
            by_run.setdefault(run, set()).add(fill)
        assert sorted(by_run) == ["0", "1", "2"] and all(len(f) == 1 for f in by_run.values())
        assert len(set.union(*by_run.values())) == 3
        assert page.locator("#hypervolume path.hv-line").count() == 3
        page.locator('#pareto circle.front[data-run="2"][data-k="0"]').click()
        assert page.locator("#detail-title").inner_text() == "Pareto solution k = 0 (seed 2)"


def test_rolling_out_a_point_shows_progress_then_worlds_and_video(tmp_path, open_page):
    run = make_push_run(tmp_path / "push-0")
    solutions = Solutions(run.path, NativeStandIn(), per_config=1, size=(64, 48))
    with serving(run.path, solutions) as base:
        page = open_page(base)
        page.locator('#pareto circle.front[data-k="0"]').click()
        page.click("#simulate")
        page.wait_for_selector("#worlds-table", timeout=120_000)
        scn = solutions.rollout_factory.built.scenario
        n_configs = len(scn.robot.start_configs) + len(scn.robot.eval_configs)
        assert page.locator("#worlds-table tr[data-config]").count() == n_configs
        page.wait_for_function("document.getElementById('progress').hidden", timeout=120_000)
        if page.locator("#frame").count() == 0 and page.locator("#video video").count() == 0:
            message = page.locator("#job-message").inner_text()
            assert "no video" in message
            no_render(message)
        if page.locator("#video video").count():  # ffmpeg here: an MP4
            assert page.locator("#video video").get_attribute("src").endswith("/known-0.mp4")
            return
        page.wait_for_function("document.getElementById('frame').naturalWidth === 64")
        first = page.locator("#frame").get_attribute("src")
        page.click("#video button")  # play: the frames follow each other
        page.wait_for_function(f"document.getElementById('frame').getAttribute('src') !== {first!r}")


def test_the_page_opened_as_localhost_exports(tmp_path, open_page):
    run = make_push_run(tmp_path / "push-0")
    with serving(run.path) as base:
        page = open_page(base.replace("127.0.0.1", "localhost"))
        page.locator('#pareto circle.front[data-k="1"]').click()
        page.click("#export")
        page.wait_for_function("document.getElementById('export-result').textContent.startsWith('wrote')")
    assert (run.path / "selected-1" / "parameters.yaml").is_file()


CROSS_SITE_POSTS = """async (target) => {
  const outcomes = [];
  for (const [path, body] of [["/api/export", {run: 0, k: 0}], ["/api/solution/0/0", {config: 0}]]) {
    for (const init of [{mode: "no-cors", headers: {"Content-Type": "text/plain"}},           // no preflight
                        {mode: "cors", headers: {"Content-Type": "application/json"}}]) {     // preflighted
      try {
        const response = await fetch(target + path, {method: "POST", body: JSON.stringify(body), ...init});
        outcomes.push(response.type);
      } catch (err) {
        outcomes.push("failed");
      }
    }
  }
  return outcomes;
}"""


def test_another_sites_page_cannot_export_or_start_a_rollout(tmp_path, open_page):
    """A page of another origin (here another explore server: another port) posts to the
    page's API as a hostile site would; the run directory stays as it was."""
    run = make_push_run(tmp_path / "push-0")
    before = sorted(p.relative_to(run.path) for p in run.path.rglob("*"))
    other = make_push_run(tmp_path / "elsewhere")
    solutions = Solutions(run.path, lambda entry: pytest.fail("a rollout was built"), per_config=1)
    with serving(run.path, solutions) as target, serving(other.path) as elsewhere:
        page = open_page(elsewhere)
        outcomes = page.evaluate(CROSS_SITE_POSTS, target)
        assert outcomes == ["opaque", "failed"] * 2  # sent blind, or refused at the preflight
        assert solutions._worker is None
    assert sorted(p.relative_to(run.path) for p in run.path.rglob("*")) == before
