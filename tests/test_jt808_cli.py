"""``csws terminals``, ``csws jt808`` and ``csws jt808-sim`` from the command line: what they print and their exits."""

from __future__ import annotations

import asyncio
import json
import pstats
import subprocess
import sys
from pathlib import Path

import pytest
import uvloop

from csws.gateways.jt808.terminals import TerminalList
from csws.gateways.jt808.texts import DriverTexts, Indication, TextsError, load_fleet_texts, text_of
from csws.networks import networks_dir
from service.jt808_cli import loop_factory, run_profiled


def csws(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "csws", *args], capture_output=True, text=True, timeout=120)


def test_terminals_are_added_listed_and_revoked(tmp_path: Path):
    file = tmp_path / "terminals.json"
    added = csws(
        "terminals", "add", "acme", "13800138000", "--category", "N", "--plate", "京A12345", "--file", str(file)
    )
    assert added.returncode == 0 and "acme/京A12345" in added.stdout
    assert file.stat().st_mode & 0o077 == 0  # readable by its owner only: it holds the secret
    listed = csws("terminals", "list", "--file", str(file))
    assert listed.stdout.split("\t")[:3] == ["13800138000", "acme", "京A12345"] and "admitted" in listed.stdout
    terminals = TerminalList(file)
    code = terminals.auth_code(terminals.terminal("013800138000"))  # leading zeros of the BCD field ignored
    assert code not in listed.stdout and json.loads(file.read_text())["secret"] not in listed.stdout
    assert terminals.admitted("13800138000", code) is not None
    assert csws("terminals", "revoke", "13800138000", "--file", str(file)).returncode == 0
    terminals.refresh()
    assert terminals.admitted("13800138000", code) is None
    readded = csws("terminals", "add", "acme", "13800138000", "--category", "N", "--file", str(file))
    assert readded.returncode == 0
    terminals.refresh()
    assert terminals.admitted("13800138000", code) is None  # a new generation: the old code stays dead


def test_bad_input_is_one_line_and_a_non_zero_exit(tmp_path: Path):
    listed = tmp_path / "listed.json"
    assert csws("terminals", "add", "acme", "13800138000", "--category", "N", "--file", str(listed)).returncode == 0
    no_lonlat = str(networks_dir() / "single_r120_left.net.xml")  # x, y only: a report's lon/lat has no place there
    settings = tmp_path / "warning.json"
    settings.write_text(json.dumps({"format": "csws-warning-settings/1", "fleets": {"acme": {"release_hold_s": -1}}}))
    cases = [
        ("jt808", "--terminals", str(tmp_path / "missing.json")),
        ("jt808", "--terminals", str(listed), "--warning-settings", str(settings), "--port", "0"),
        ("jt808", "--terminals", str(listed), "--max-connections", "0"),
        ("jt808", "--terminals", str(listed), "--frames-per-s", "nan"),
        ("jt808", "--terminals", str(listed), "--frames-burst", "0.5"),
        ("jt808", "--terminals", str(listed), "--idle-s", "-1"),
        ("jt808", "--terminals", str(listed), "--net", no_lonlat, "--port", "0"),
        ("terminals", "add", "acme", "12ab", "--category", "N", "--file", str(tmp_path / "t.json")),
        ("terminals", "add", "acme", "1380", "--category", "X9", "--file", str(tmp_path / "t.json")),
        ("terminals", "revoke", "1380", "--file", str(tmp_path / "missing.json")),
        ("jt808-sim", str(tmp_path / "missing.csv")),
        ("jt808-sim", str(tmp_path / "missing.csv"), "--gateway", "no-port"),
    ]
    for args in cases:
        result = csws(*args)
        assert result.returncode == 2, (args, result.stderr)
        assert result.stderr.startswith("csws: error: ") and result.stderr.count("\n") == 1, result.stderr
        assert "Traceback" not in result.stderr


def test_texts_change_only_when_the_indication_does():
    texts = DriverTexts()
    quiet, one, two = Indication(0, "active"), Indication(1, "active"), Indication(2, "active")
    off, fault = Indication(0, "off"), Indication(0, "fault")
    assert text_of(texts, None, quiet, None) is None
    assert text_of(texts, quiet, one, 75.8) == texts.level1.replace("{speed_kmh}", "75")
    assert text_of(texts, one, one, 75.8) is None
    assert text_of(texts, one, two, 87.3) == texts.level2.replace("{speed_kmh}", "87")  # 6.2.1: level 2 first
    assert text_of(texts, two, one, 75.8) is None and text_of(texts, one, quiet, None) is None
    assert text_of(texts, quiet, off, None) == texts.switched_off and text_of(texts, off, off, None) is None
    assert text_of(texts, off, quiet, None) == texts.restored and text_of(texts, one, fault, None) == texts.fault
    assert texts.level1 != texts.level2  # 5.5.1: the two levels clearly differ


def test_fleet_texts_are_read_and_bad_files_named(tmp_path: Path):
    good = tmp_path / "texts.json"
    good.write_text(json.dumps({"acme": {"level1": "Curve ahead, slow to {speed_kmh} km/h"}}))
    assert load_fleet_texts(good)["acme"].level1.startswith("Curve ahead")
    assert load_fleet_texts(good)["acme"].level2 == DriverTexts().level2
    for content in ({"acme": {"level3": "x"}}, {"acme": {"level1": "☃"}}, ["x"]):
        bad = tmp_path / "bad.json"
        bad.write_text(json.dumps(content))
        try:
            load_fleet_texts(bad)
        except TextsError as error:
            assert str(bad) in str(error)
        else:
            raise AssertionError(f"{content} was accepted")


def test_a_fault_is_told_only_once_it_lasts():
    """5.5.3 asks for a clear fault indication; one report that matches no road is not one to speak of."""
    from csws.gateways.jt808.texts import FAULT_CONFIRM_S, Announcer

    texts = DriverTexts()
    announcer = Announcer(texts)
    assert announcer.update("active", 1, 75.8, 0.0) == (texts.level1.replace("{speed_kmh}", "75"), False)
    assert announcer.update("fault", 0, None, 1.0) is None  # a second of fault: nothing said
    assert announcer.update("active", 1, 75.8, 2.0) is None  # level 1 again: already told
    assert announcer.update("fault", 0, None, 3.0) is None
    assert announcer.update("fault", 0, None, 3.0 + FAULT_CONFIRM_S) == (texts.fault, True)
    assert announcer.update("fault", 0, None, 4.0 + FAULT_CONFIRM_S) is None
    assert announcer.update("active", 0, None, 5.0 + FAULT_CONFIRM_S) == (texts.restored, False)
    assert announcer.update("active", 2, 87.3, 6.0 + FAULT_CONFIRM_S) == (
        texts.level2.replace("{speed_kmh}", "87"),
        True,
    )


def test_the_event_loop_is_uvloop_where_installed_and_asyncio_when_asked_or_missing(monkeypatch):
    """``--loop auto`` takes uvloop when it imports and the standard loop when it does not; ``--loop asyncio`` always
    the standard loop; ``--loop uvloop`` without uvloop is an error, not a silent fallback."""
    loops: list[type] = []

    async def which() -> None:
        loops.append(type(asyncio.get_running_loop()))

    run_profiled(which(), loop_factory("auto"), None)
    run_profiled(which(), loop_factory("uvloop"), None)
    run_profiled(which(), loop_factory("asyncio"), None)
    assert loops[0] is loops[1] is uvloop.Loop
    assert issubclass(loops[2], asyncio.BaseEventLoop) and loops[2] is not uvloop.Loop
    monkeypatch.setitem(sys.modules, "uvloop", None)  # as if it were not installed
    assert loop_factory("auto") is None
    with pytest.raises(ValueError, match="uvloop is not installed"):
        loop_factory("uvloop")


def test_the_profile_of_the_event_loop_is_written(tmp_path: Path):
    """``--profile``: the loop thread's cProfile is written when the loop ends, and names the coroutine it ran."""

    async def named_for_the_profile() -> None:
        await asyncio.sleep(0)

    run_profiled(named_for_the_profile(), loop_factory("asyncio"), tmp_path / "loop.prof")
    functions = pstats.Stats(str(tmp_path / "loop.prof")).stats  # type: ignore[attr-defined]
    assert any(name == "named_for_the_profile" for _, _, name in functions)


def test_the_two_gateway_compose_example_runs_gateways_on_its_redis_behind_its_balancer():
    """examples/jt808: each gateway's command is a ``csws jt808`` the parser takes, on the port the balancer sends to,
    sharing the Redis service, with the terminal file mounted where it reads it; the balancer's backends are the two."""
    import yaml

    from csws.cli import build_parser

    folder = Path(__file__).resolve().parents[1] / "examples" / "jt808"
    services = yaml.safe_load((folder / "compose.yaml").read_text())["services"]
    gateways = {name: service for name, service in services.items() if name.startswith("gateway-")}
    assert len(gateways) == 2 and services["redis"]["command"][-1] == "always"
    balancer = (folder / "haproxy.cfg").read_text()
    backends = [line.split()[2] for line in balancer.splitlines() if line.strip().startswith("server ")]
    assert (folder / "haproxy.cfg").name in services["balancer"]["volumes"][0]
    for name, gateway in gateways.items():
        args = build_parser().parse_args([str(word) for word in gateway["command"]][1:])
        assert args.command == "jt808" and args.host == "0.0.0.0" and args.state == "redis://redis:6379/0"
        assert f"{name}:{args.port}" in backends
        mounted = {volume.split(":")[1]: volume.split(":")[0] for volume in gateway["volumes"]}
        assert mounted[str(args.terminals)] == "./terminals.json"
        assert (folder / gateway["build"] / "Dockerfile").exists()
    assert services["balancer"]["ports"] == ["6808:6808"] and "bind :6808" in balancer
