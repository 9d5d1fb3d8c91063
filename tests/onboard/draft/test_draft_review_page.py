"""``drivemap draft DOC --review review.html``: the review page, parsed here and opened in a real browser.

The browser test (``tools`` tier) drives the system's Chromium through Selenium: the page images load,
every drafted row is outlined on its page image where the document draws it, a register's source link
lands on its row, and the outline is drawn (pixels of a screenshot). Without Chromium it fails saying so.
"""

from __future__ import annotations

import io
import os
import re
import shutil
from html.parser import HTMLParser
from pathlib import Path
from typing import Any

import openpyxl
import pytest
import yaml
from test_draft_gaps import _table

from drivemap.cli import main


def _manual(path: Path) -> Path:
    """A two-page register list: a ruled table continued on the next page, one reserved row."""
    from fpdf import FPDF

    pdf = FPDF()
    pdf.set_font("Helvetica", size=9)
    pdf.add_page()
    pdf.cell(text="3.2 Input registers (function code 04)", new_x="LMARGIN", new_y="NEXT")
    _table(pdf, [["Address", "Name", "Description", "Type", "Unit"],
                 ["0x0000", "GridVoltage", "Grid voltage", "U16", "0.1V"],
                 ["0x0001", "GridCurrent", "Grid current", "U16", "0.01A"],
                 ["0x0002", "Reserved", "Reserved", "", ""],
                 ["0x0003", "GridFrequency", "Grid frequency", "U16", "0.01Hz"]], (25, 40, 60, 20, 20))
    pdf.output(str(path))
    return path


class _Page(HTMLParser):
    def __init__(self) -> None:
        super().__init__()
        self.ids: set[str] = set()
        self.hrefs: list[str] = []
        self.marks: list[str] = []
        self.images = 0

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        a = dict(attrs)
        if a.get("id"):
            self.ids.add(str(a["id"]))
        if tag == "a" and (a.get("href") or "").startswith("#"):
            self.hrefs.append(str(a["href"])[1:])
        if "mark" in (a.get("class") or "").split():
            self.marks.append(str(a.get("class")))
        if tag == "img" and (a.get("src") or "").startswith("data:image/png;base64,"):
            self.images += 1


def _draft(tmp_path: Path, document: Path, *extra: str) -> tuple[int, Path, Path]:
    out, page = tmp_path / "maps" / "dev.yaml", tmp_path / "review.html"
    code = main(["draft", str(document), "-o", str(out), "--review", str(page), *extra])
    return code, out, page


def test_review_page_of_a_pdf_outlines_each_used_row_and_links_resolve(tmp_path: Path) -> None:
    code, out, page = _draft(tmp_path, _manual(tmp_path / "manual.pdf"))
    assert code == 0
    names = [r["name"] for r in yaml.safe_load(out.read_text(encoding="utf-8"))["registers"]]
    parsed = _Page()
    parsed.feed(page.read_text(encoding="utf-8"))
    assert parsed.images == 1
    assert len([m for m in parsed.marks if "used" in m.split()]) == len(names) == 3
    assert len([m for m in parsed.marks if "skipped" in m.split()]) == 1
    assert set(parsed.hrefs) <= parsed.ids, set(parsed.hrefs) - parsed.ids
    for name in names:
        assert f"reg-{name}" in parsed.ids
    assert "Rows skipped: 1" in page.read_text(encoding="utf-8")


def test_map_and_page_are_written_as_the_users_files(tmp_path: Path) -> None:
    old = os.umask(0o027)
    try:
        code, out, page = _draft(tmp_path, _manual(tmp_path / "manual.pdf"))
    finally:
        os.umask(old)
    assert code == 0
    assert out.stat().st_mode & 0o777 == page.stat().st_mode & 0o777 == 0o640


def test_review_page_of_a_spreadsheet_shows_the_cells_read(tmp_path: Path) -> None:
    path = tmp_path / "list.xlsx"
    wb = openpyxl.Workbook()
    ws = wb.active
    assert ws is not None
    ws.title = "Registers"
    for row in (["Address", "Name", "Units", "Type"], [1000, "Voltage", "0.1 V", "UINT16"],
                [1001, "Current", "0.01 A", "UINT16"], ["Reserved", "", "", ""]):
        ws.append(row)
    wb.save(path)
    code, out, page = _draft(tmp_path, path)
    assert code == 0
    text = page.read_text(encoding="utf-8")
    parsed = _Page()
    parsed.feed(text)
    assert parsed.images == 0
    assert len(re.findall(r'<tr class="used"', text)) == 2
    assert set(parsed.hrefs) <= parsed.ids


def test_review_page_is_refused_with_a_wrong_name_or_over_a_file(tmp_path: Path, capsys: Any) -> None:
    doc = _manual(tmp_path / "manual.pdf")
    assert main(["draft", str(doc), "-o", str(tmp_path / "a.yaml"), "--review", str(tmp_path / "r.txt")]) == 1
    assert "the review page is an HTML file" in capsys.readouterr().err
    (tmp_path / "r.html").write_text("mine", encoding="utf-8")
    assert main(["draft", str(doc), "-o", str(tmp_path / "a.yaml"), "--review", str(tmp_path / "r.html")]) == 1
    assert "exists; not overwritten" in capsys.readouterr().err
    assert (tmp_path / "r.html").read_text(encoding="utf-8") == "mine"
    assert not (tmp_path / "a.yaml").exists()


def _browser() -> Any:
    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    driver = shutil.which("chromedriver")
    if not chromium or not driver:
        pytest.fail("Chromium and chromedriver are needed (apt-get install chromium chromium-driver; .ci/run does)")
    try:
        from selenium import webdriver
        from selenium.webdriver.chrome.service import Service
    except ImportError:
        pytest.fail("selenium is needed (pip install -e '.[test]')")
    options = webdriver.ChromeOptions()
    options.binary_location = chromium
    for flag in ("--headless=new", "--no-sandbox", "--disable-gpu", "--window-size=1400,1200"):
        options.add_argument(flag)
    return webdriver.Chrome(service=Service(executable_path=driver), options=options)


@pytest.mark.tools
def test_review_page_in_a_real_browser(tmp_path: Path) -> None:
    from PIL import Image
    from selenium.webdriver.common.by import By

    code, out, page = _draft(tmp_path, _manual(tmp_path / "manual.pdf"))
    assert code == 0
    names = [r["name"] for r in yaml.safe_load(out.read_text(encoding="utf-8"))["registers"]]
    browser = _browser()
    try:
        browser.get(page.resolve().as_uri())
        img = browser.find_element(By.CSS_SELECTOR, ".shot img")
        assert browser.execute_script("return arguments[0].complete && arguments[0].naturalWidth", img) > 0
        box = img.rect
        marks = browser.find_elements(By.CSS_SELECTOR, ".mark.used")
        assert len(marks) == len(names)
        tops = []
        for mark in marks:
            r = mark.rect
            assert r["width"] > 50 and r["height"] > 3
            assert box["x"] <= r["x"] and r["x"] + r["width"] <= box["x"] + box["width"] + 1
            assert box["y"] <= r["y"] and r["y"] + r["height"] <= box["y"] + box["height"] + 1
            tops.append(r["y"])
        assert tops == sorted(tops)  # the rows outlined in the document's order, each on its own line
        assert len(set(round(t) for t in tops)) == len(tops)
        # a register's source link lands on its row of the table as read
        link = browser.find_element(By.CSS_SELECTOR, f"#reg-{names[1]} a")
        browser.execute_script("arguments[0].click()", link)
        target = browser.execute_script("return location.hash")
        assert target.startswith("#row-")
        row = browser.find_element(By.ID, target[1:])
        assert names[1] in row.text
        # the outline is drawn: the mark's border pixels are the "used" green
        mark = marks[0]
        browser.execute_script("arguments[0].scrollIntoView()", mark)
        shot = Image.open(io.BytesIO(mark.screenshot_as_png)).convert("RGB")
        data = shot.tobytes()
        pixels = (data[i:i + 3] for i in range(0, len(data), 3))
        greens = sum(1 for r, g, b in pixels if g > 100 and r < 80 and b < 100)
        assert greens > 20, greens
    finally:
        browser.quit()
