"""The HTTP examples of the README and docs/service.md, asked of a fresh service: what they answer now.

A document says which service its answers come from ("The answers below are real, from
`csws serve --net networks/t7_left.net.xml`"); each such sentence starts a fresh service (the app
in this process, its vehicles in memory) serving what it names, and every example after it, in
order, is asked of that service. An example is a ```bash block whose command is ``curl`` followed by
a ```json block with the answer it shows, or a ``curl`` line whose comment is the answer
(``curl -s .../healthz    # {"status":"ok"}``). Where a document shortens an answer it writes ``...``,
which stands for any text.

    python docs/examples.py            # every example's request and the answer it gets now
    python docs/examples.py --check    # only the examples whose answer differs from the document's
    python docs/examples.py --write    # put the answers of today in the documents (shortened ones stay: edit those)

``tests/test_doc_examples.py`` keeps the documents equal to what the service answers.
"""

from __future__ import annotations

import argparse
import re
import shlex
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: The documents whose examples are run.
DOCUMENTS = (ROOT / "README.md", ROOT / "docs" / "service.md")
#: A sentence naming the service the examples after it ask.
SERVED_BY = re.compile(r"answers? below (?:is|are) real, from\s+`csws serve([^`]*)`")
#: A bash block, and the json block right after it if there is one.
BLOCKS = re.compile(r"```bash\n(?P<bash>.*?)```\n(?:```json\n(?P<json>.*?)```)?", re.S)
#: Where documents shorten an answer.
ELIDED = "..."


@dataclass(frozen=True)
class Example:
    """One example: where it is, the service it asks (``csws serve`` options), its command and the answer shown.

    Attributes
    ----------
    document, line
        The document and the line of its command.
    serve
        The options of the ``csws serve`` it asks (its document's latest "answers below are real" sentence).
    command
        The ``curl`` command, continuation lines joined.
    shown
        The answer the document shows.
    """

    document: Path
    line: int
    serve: str
    command: str
    shown: str

    @property
    def where(self) -> str:
        """``document:line``, relative to the repository."""
        return f"{self.document.relative_to(ROOT)}:{self.line}"


def examples(document: Path) -> list[Example]:
    """The examples of a document, in order, each with the service its document says answered it."""
    text = document.read_text("utf-8")
    services = [(match.start(), match.group(1).strip()) for match in SERVED_BY.finditer(text)]
    found = []
    for block in BLOCKS.finditer(text):
        serving = [options for start, options in services if start < block.start()]
        if not serving:
            continue
        line = text.count("\n", 0, block.start()) + 2
        for command, shown in _commands(block.group("bash"), block.group("json")):
            found.append(Example(document, line, serving[-1], command, shown))
    return found


def _commands(bash: str, json: str | None) -> Iterator[tuple[str, str]]:
    """The ``curl`` commands of a bash block with the answers shown: the json block after it for a block of
    one command, else each command's own comment where that is a JSON document."""
    commands = [line for line in bash.replace("\\\n", " ").splitlines() if line.strip().startswith("curl ")]
    if json is not None and len(commands) == 1:
        yield commands[0], json.strip()
        return
    for command in commands:
        request, _, comment = command.partition("  #")
        if comment.strip().startswith("{"):
            yield request.strip(), comment.strip()


@dataclass(frozen=True)
class Request:
    """What a ``curl`` command asks: method, path with query, headers, body."""

    method: str
    path: str
    headers: dict[str, str]
    body: bytes | None


def request_of(command: str) -> Request:
    """The request of a ``curl`` command (``-X``, ``-H``, ``-d`` and a URL on the documents' host)."""
    words = shlex.split(command, comments=True)[1:]
    method, headers, body, url = "", {}, None, ""
    while words:
        word = words.pop(0)
        if word == "-X":
            method = words.pop(0)
        elif word == "-H":
            name, _, value = words.pop(0).partition(":")
            headers[name.strip()] = value.strip()
        elif word in ("-d", "--data"):
            body = words.pop(0).encode("utf-8")
        elif word.startswith("http"):
            url = word
        elif word != "-s":
            raise ValueError(f"curl option {word!r} is not one the examples use")
    path = re.sub(r"^https?://[^/]+", "", url)
    return Request(method or ("POST" if body is not None else "GET"), path, headers, body)


def agrees(shown: str, answer: str) -> bool:
    """Whether an answer is the one shown, where ``...`` in the shown stands for any text."""
    pattern = ".*?".join(re.escape(part) for part in shown.split(ELIDED))
    return re.fullmatch(pattern, answer, re.S) is not None


def _fresh_service(serve: str):
    """A client of a fresh service started with the ``csws serve`` options ``serve`` (vehicles in memory)."""
    from fastapi.testclient import TestClient

    from service.app import create_app
    from service.cli import add_commands
    from service.run import settings_from_args

    parser = argparse.ArgumentParser(prog="csws")
    add_commands(parser.add_subparsers(dest="command"))
    args = parser.parse_args(["serve", "--state-db", ":memory:", *shlex.split(serve)])
    args.net = None if args.net is None else [net if net.is_absolute() else ROOT / net for net in args.net]
    return TestClient(create_app(settings_from_args(args)))


def answers(documents: tuple[Path, ...] = DOCUMENTS) -> Iterator[tuple[Example, str]]:
    """Every example of ``documents`` with the answer it gets now: a fresh service for each run of examples
    that one sentence of a document names."""
    for document in documents:
        serve, client = None, None
        try:
            for example in examples(document):
                if example.serve != serve or client is None:
                    if client is not None:
                        client.__exit__(None, None, None)
                    serve, client = example.serve, _fresh_service(example.serve).__enter__()
                request = request_of(example.command)
                response = client.request(request.method, request.path, headers=request.headers, content=request.body)
                yield example, response.text
        finally:
            if client is not None:
                client.__exit__(None, None, None)


def write(example: Example, answer: str) -> bool:
    """Put ``answer`` in the example's document in place of the one it shows; False for a shortened one
    (which needs an editor's hand)."""
    if ELIDED in example.shown:
        return False
    text = example.document.read_text("utf-8")
    example.document.write_text(text.replace(example.shown, answer, 1), "utf-8")
    return True


def main(argv: list[str] | None = None) -> int:
    """Print every example's request and answer (``--check``: only those that differ from the documents;
    ``--write``: and put them in)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    chosen = parser.add_mutually_exclusive_group()
    chosen.add_argument("--check", action="store_true", help="print only the answers the documents do not show")
    chosen.add_argument("--write", action="store_true", help="put the answers the documents do not show in them")
    options = parser.parse_args(argv)
    differ = 0
    for example, answer in list(answers()):
        same = agrees(example.shown, answer)
        written = not same and options.write and write(example, answer)
        differ += not (same or written)
        if not ((options.check or options.write) and same):
            status = "" if same else ("  (written)" if written else "  (differs from the document)")
            print(f"# {example.where}: csws serve {example.serve}{status}\n{example.command}\n{answer}\n")
    return 1 if differ else 0


if __name__ == "__main__":
    sys.exit(main())
