"""``fawtgym wind`` command (envs/wind/cli.py)."""

import pytest

from fawtgym.envs.wind.cli import main


def test_cli_prints_table3_comparison_and_writes_plot(tmp_path, capsys):
    out = tmp_path / "wind.png"
    assert main(["--preset", "fawt-50", "--seconds", "4", "--fields", "8", "--plot", str(out)]) == 0
    text = capsys.readouterr().out
    assert "Table 3 50%" in text and "8.213" in text
    gen = next(line for line in text.splitlines() if line.startswith("generated")).split()
    assert float(gen[1]) == pytest.approx(8.213, rel=0.02)
    assert float(gen[2]) == pytest.approx(0.116, rel=0.10)
    assert out.stat().st_size > 10_000


def test_cli_other_presets_and_bad_input(tmp_path):
    assert main(["--preset", "dryden-light", "--seconds", "2", "--dt", "0.01", "--plot", str(tmp_path / "d.png")]) == 0
    assert main(["--preset", "fawt", "--duty", "45", "--seconds", "1"]) == 0
    assert main(["--preset", "fawt", "--duty", "45%", "--seconds", "1"]) == 0
    for bad in (["--preset", "fawt", "--duty", "150"], ["--preset", "fawt", "--duty", "0.45"],
                ["--preset", "fawt-30", "--seconds", "0.001"], ["--preset", "fawt-50", "--duty", "30"]):
        with pytest.raises(SystemExit) as e:
            main([*bad, "--seconds", "1"] if "--seconds" not in bad else bad)
        assert e.value.code == 2
