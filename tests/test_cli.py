"""The csws command as a user runs it: a real process, its output and its exit status."""

from __future__ import annotations

import json
import shutil
import socket
import subprocess
import sys
from pathlib import Path

import pytest

from csws.networks import networks_dir

SUBCOMMANDS = [["networks"], ["networks", "build"], ["networks", "verify"], ["curves"]]


def _csws(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "csws", *args], capture_output=True, text=True, timeout=300)


def test_help_lists_every_subcommand():
    result = _csws("--help")
    assert result.returncode == 0
    for name in ("networks", "curves"):
        assert name in result.stdout


@pytest.mark.parametrize("words", SUBCOMMANDS, ids=" ".join)
def test_every_subcommand_has_help(words):
    result = _csws(*words, "--help")
    assert result.returncode == 0 and "usage: csws" in result.stdout


@pytest.mark.slow
def test_verify_passes_on_the_bundled_networks():
    result = _csws("networks", "verify")
    assert result.returncode == 0, result.stdout + result.stderr
    index = json.loads((networks_dir() / "index.json").read_text())
    curves = sum(len(json.loads((networks_dir() / e["truth_file"]).read_text())["curves"]) for e in index["networks"])
    assert f"{curves}/{curves} curves within 1 m" in result.stdout


def test_verify_fails_with_status_1_when_a_truth_is_wrong(tmp_path: Path):
    for item in networks_dir().glob("single_r40_left.*"):
        shutil.copy(item, tmp_path)
    index = json.loads((networks_dir() / "index.json").read_text())
    index["networks"] = [e for e in index["networks"] if e["name"] == "single_r40_left"]
    (tmp_path / "index.json").write_text(json.dumps(index))
    truth_file = tmp_path / "single_r40_left.truth.json"
    truth = json.loads(truth_file.read_text())
    truth["curves"][0]["start_s"] += 2.0  # a truth 2 m off: the extractor must disagree
    truth_file.write_text(json.dumps(truth))
    result = _csws("networks", "verify", "--dir", str(tmp_path))
    assert result.returncode == 1
    assert "FAIL" in result.stdout


def test_curves_lists_the_curve_of_a_track_as_json():
    result = _csws("curves", str(networks_dir() / "single_r120_left.net.xml"), "--format", "json")
    assert result.returncode == 0
    curves = [c for c in json.loads(result.stdout) if not c["lane_id"].startswith(":")]
    truth = json.loads((networks_dir() / "single_r120_left.truth.json").read_text())["curves"][0]
    assert len(curves) == 1
    assert curves[0]["start_pos_m"] == pytest.approx(truth["lanes"][0]["start_pos_m"], abs=1.0)
    assert curves[0]["radius_m"] == pytest.approx(120.0, rel=0.01)


@pytest.mark.parametrize(
    "args, message",
    [
        (["curves", "/no/such/file.net.xml"], "csws: error:"),
        (["networks", "verify", "--dir", "/"], "has no index.json"),
        (["networks", "verify", "--tolerance-m", "-1"], "must be a positive finite number"),
        (["curves", "x.net.xml", "--warning-radius-m", "nan"], "must be a positive finite number"),
        (["conformance", "--out", __file__], "is a file, not a folder: give a folder"),
        (["cosim", "--out", __file__], "is a file, not a folder: give a folder"),
        (["cosim", "--service", "http://127.0.0.1:9", "--api-key-file", "/no/such/key"], "cannot read the key file"),
        (["cosim", "--api-key-file", __file__], "give --service URL with it"),
        (["import-osm", "x.osm", "-o", "x.txt"], "give NAME.net.xml or NAME.net.xml.gz"),
    ],
)
def test_bad_input_is_one_line_and_a_non_zero_exit(args, message):
    result = _csws(*args)
    assert result.returncode == 2
    assert message in result.stderr
    assert "Traceback" not in result.stderr
    assert message in result.stderr.strip().splitlines()[-1]  # the last line says what is wrong


@pytest.mark.slow
def test_output_read_only_in_part_ends_quietly():
    """``csws curves NET | head -1``: the reader goes away; csws stops without a word, with the
    status a program ended by SIGPIPE has."""
    with subprocess.Popen(
        [sys.executable, "-m", "csws", "curves", str(networks_dir() / "badhersfeld.net.xml.gz")],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    ) as process:
        process.stdout.readline()
        process.stdout.close()
        stderr = process.stderr.read()
        assert process.wait(timeout=120) == 141
    assert stderr == b""


@pytest.mark.slow
@pytest.mark.parametrize("workers", ["1", "2"])
def test_a_port_in_use_is_one_line_before_anything_is_served(tmp_path, workers):
    with socket.socket() as held:
        held.bind(("127.0.0.1", 0))
        held.listen()
        port = held.getsockname()[1]
        result = _csws(
            "serve",
            "--port",
            str(port),
            "--net",
            str(networks_dir() / "t7_left.net.xml"),
            "--workers",
            workers,
            "--state-db",
            str(tmp_path / "vehicles.db"),
        )
    assert result.returncode == 2 and result.stdout == ""
    assert result.stderr.strip().splitlines() == [
        f"csws: error: cannot listen on 127.0.0.1:{port}: it is in use (another program, or another csws serve); "
        "give another --port"
    ]
