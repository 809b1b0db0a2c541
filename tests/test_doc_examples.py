"""The HTTP examples of the README and docs/service.md answer what the documents show: each one asked
of a fresh service serving what its document names (``docs/examples.py``)."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

EXAMPLES_SCRIPT = Path(__file__).resolve().parents[1] / "docs" / "examples.py"


def _examples_module():
    """``docs/examples.py`` as a module (docs/ is no package)."""
    spec = importlib.util.spec_from_file_location("doc_examples", EXAMPLES_SCRIPT)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


examples = _examples_module()


def test_the_curl_commands_are_read_as_curl_sends_them() -> None:
    request = examples.request_of(
        "curl -s -X PUT http://127.0.0.1:8000/v1/vehicles/t-1 -H 'Content-Type: application/json' "
        """-d '{"switched_on": false}'   # a comment"""
    )
    assert (request.method, request.path, request.body) == ("PUT", "/v1/vehicles/t-1", b'{"switched_on": false}')
    assert request.headers == {"Content-Type": "application/json"}
    assert examples.request_of("curl -s 'http://127.0.0.1:8000/v1/horizon?x=1&y=2'").method == "GET"


def test_a_shortened_answer_agrees_with_any_text_where_it_is_shortened() -> None:
    assert examples.agrees('{"a":[1,...],"b":...}', '{"a":[1,2,3],"b":{"c":4}}')
    assert not examples.agrees('{"a":[1,...],"b":5}', '{"a":[1,2,3],"b":4}')
    assert not examples.agrees('{"a":1}', '{"a":1,"b":2}')


def test_every_document_has_examples_and_names_their_service() -> None:
    found = [example for document in examples.DOCUMENTS for example in examples.examples(document)]
    assert {example.document.name for example in found} == {"README.md", "service.md"}
    assert "" in {example.serve for example in found}  # the default serve, the city
    assert len(found) >= 15


@pytest.mark.slow
def test_every_example_answers_what_its_document_shows() -> None:
    differ = [
        f"{example.where}: {example.command}\nshows   {example.shown}\nanswers {answer}"
        for example, answer in examples.answers()
        if not examples.agrees(example.shown, answer)
    ]
    assert not differ, "\n\n".join(differ) + "\n\n(python docs/examples.py --write puts today's answers in)"
