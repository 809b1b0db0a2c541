"""The Dockerfile, linted (no container engine is needed): a slim Python base, ``pip install .`` of the
sources it copies, ``csws serve`` on 0.0.0.0 at the port it exposes, and a key file setting the
service really reads."""

from __future__ import annotations

import json
import shlex
from pathlib import Path

from csws.curvature.cache import profile_cache_dir
from service.settings import ServiceSettings

ROOT = Path(__file__).resolve().parents[1]


def _instructions() -> list[tuple[str, str]]:
    """(INSTRUCTION, arguments) of the Dockerfile, continuation lines joined, comments left out."""
    text = (ROOT / "Dockerfile").read_text().replace("\\\n", " ")
    lines = [line.strip() for line in text.splitlines() if line.strip() and not line.lstrip().startswith("#")]
    return [(line.split(None, 1)[0].upper(), line.split(None, 1)[1]) for line in lines]


def _all(name: str) -> list[str]:
    return [arguments for instruction, arguments in _instructions() if instruction == name]


def test_the_image_is_a_slim_python_with_csws_installed_from_its_sources() -> None:
    assert _instructions()[0][0] == "FROM"
    [base] = _all("FROM")
    image, _, tag = base.partition(":")
    assert image == "python" and tag.endswith("-slim") and tuple(map(int, tag.split("-")[0].split("."))) >= (3, 11)
    copied = {shlex.split(arguments)[0] for arguments in _all("COPY")}
    assert {"pyproject.toml", "csws", "service", "networks"} <= copied
    assert all((ROOT / path).exists() for path in copied)
    installs = [shlex.split(run) for run in _all("RUN") if "pip install" in run]
    assert any(
        "." in words[words.index("install") + 1 : words.index("&&") if "&&" in words else None] for words in installs
    )


def test_it_serves_on_all_addresses_at_the_exposed_port_with_a_key_file_the_service_reads(monkeypatch) -> None:
    [command] = _all("CMD")
    argv = json.loads(command)  # the exec form: signals reach csws serve
    assert argv[:2] == ["csws", "serve"]
    assert argv[argv.index("--host") + 1] == "0.0.0.0"
    [exposed] = _all("EXPOSE")
    assert argv[argv.index("--port") + 1] == exposed
    environment = dict(pair.split("=", 1) for arguments in _all("ENV") for pair in shlex.split(arguments))
    read = {f"CSWS_{name.upper()}" for name in ServiceSettings.model_fields}
    assert set(environment) - read == {"CSWS_CACHE_DIR"}
    with monkeypatch.context() as patch:  # the profile cache's folder, read by the library
        patch.setenv("CSWS_CACHE_DIR", environment["CSWS_CACHE_DIR"])
        assert profile_cache_dir() == Path(environment["CSWS_CACHE_DIR"])
    # On 0.0.0.0 the service refuses to start without keys: the image names the key file.
    settings = ServiceSettings(_env_file=None, host="0.0.0.0", nets=[], api_keys_file=environment["CSWS_API_KEYS_FILE"])
    assert settings.api_keys_file == Path(environment["CSWS_API_KEYS_FILE"])
