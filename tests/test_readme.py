"""The README says what the package measured: its speed table is the speeds file's."""

from pathlib import Path

from pianist.control.registry import controller_help, measured_speeds, speeds_table

README = Path(__file__).resolve().parent.parent / "README.md"


def test_the_readme_speed_table_is_the_measured_one():
    speeds = measured_speeds()
    assert speeds.get("kinds"), "src/pianist/control/speeds.json is missing or empty"
    text = README.read_text()
    block = text.split("<!-- speeds: benchmarks/bench_speeds.py -->\n")[1]
    block = block.split("\n<!-- /speeds -->")[0]
    assert block == speeds_table(speeds), "run python benchmarks/bench_speeds.py --readme"


def test_the_help_quotes_the_same_speeds():
    speeds = measured_speeds()["kinds"]
    text = controller_help()
    for kind in ("planner", "refine", "search", "mpc", "generalist"):
        line = next(line for line in text.splitlines() if line.startswith(f"{kind}: "))
        assert "Measured: " in line and "faithful" in line and "fast" in line, line
        assert kind in speeds
