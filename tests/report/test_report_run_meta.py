"""Plan and evaluate reports carry the same metadata as the adjustment reports (issue 42):
baarda's version, the date, the run id and the command, from the run that wrote them."""

import json
import re

from baarda.cli import main
from baarda.output.run_folder import package_version


def meta_of(page: str) -> dict[str, str]:
    m = re.search(r'<section id="metadata">.*?<dl class="meta">(.*?)</dl>', page, re.S)
    assert m, "no metadata section"
    return dict(re.findall(r"<dt>([^<]*)</dt><dd>([^<]*)</dd>", m.group(1)))


def test_plan_and_evaluate_reports_state_their_run(tmp_path):
    out = tmp_path / "plan"
    assert main(["plan", "-o", str(out), "--strips", "2", "--photos", "3", "-q"]) == 0
    ev = tmp_path / "ev"
    assert main(["evaluate", "-o", str(ev), "--trials", "1", "--strips", "2", "--photos",
                 "3", "--blunders", "1", "--strategies", "snoop", "-q"]) == 0
    for page, folder in ((out / "plan_report.html", out), (ev / "report.html", ev)):
        run = json.loads((folder / "run.json").read_text())
        meta = meta_of(page.read_text(encoding="utf-8"))
        assert meta["baarda version"] == package_version() == run["baarda"]
        assert meta["run"] == run["run"]
        assert meta["processed"] == run["started"]
        assert meta["command"] == run["command"] and meta["command"].startswith("baarda ")
