"""The licenses a lecturer needs to reuse the collection: code under MIT, notebook text under CC BY 4.0."""

import subprocess
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_license_files_name_what_they_cover():
    code = (ROOT / "LICENSE").read_text()
    text = (ROOT / "LICENSE-notebooks").read_text()
    assert code.startswith("MIT License") and "LICENSE-notebooks" in code
    assert "Creative Commons Attribution 4.0 International Public License" in text
    for section in range(1, 9):
        assert f"Section {section} --" in text
    assert "observation log is not part of this" in code.replace("\n", " ")
    assert "observation log is not part of this" in text.replace("\n", " ")


def test_pyproject_and_readme_state_both_licenses():
    meta = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    assert meta["license"]["text"] == "MIT AND CC-BY-4.0"
    readme = (ROOT / "README.md").read_text()
    assert "LICENSE-notebooks" in readme and "CC BY 4.0" in readme and "MIT" in readme


def test_the_course_log_is_not_in_the_repository():
    files = subprocess.run(["git", "ls-files"], cwd=ROOT, capture_output=True, text=True, check=True).stdout
    names = {Path(line).name for line in files.splitlines()}
    assert "README.md" in names
    assert not names & {"ydata.csv", "tvec.csv", "Qtrue.csv", "Rtrue.csv", "cooplocalization_finalproj_KFdata.mat"}
