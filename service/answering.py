"""Warnings over HTTP: a query or a batch decoded, answered on the work thread, encoded, and counted.

:class:`Answering` is what the warning routes depend on (:mod:`service.deps`): one dependency
holding the service, the work thread and the metrics, since each dependency FastAPI resolves costs
the single query, the hottest route, its own share of time.
"""

from __future__ import annotations

from dataclasses import dataclass

from .answers import EncodedAnswers, WarningService
from .batch_items import ItemErrors, decode_items
from .decoding import DecodedBatch, DecodedQuery, decode
from .metrics import Metrics
from .schemas import BATCH_ADAPTER, QUERY_ADAPTER
from .timing import Stages
from .work import WorkThread

__all__ = ["Answering"]


@dataclass(frozen=True)
class Answering:
    """Answers request bodies of warnings.

    Attributes
    ----------
    service
        Answers decoded queries.
    work
        The thread the work runs on, in arrival order (:mod:`service.work`).
    metrics
        Counts the answers by state and level.
    """

    service: WarningService
    work: WorkThread
    metrics: Metrics

    async def one(self, body: bytes, fleet: str) -> bytes:
        """The JSON answer to the body of one query of ``fleet``."""
        answers: EncodedAnswers = await self.work.run(self._one, body, fleet)
        self.metrics.observe_answers(answers.state, answers.level)
        return answers.json(0)

    async def batch(self, body: bytes, fleet: str, stages: Stages, atomic: bool = False) -> bytes:
        """The JSON answers to the body of a batch of ``fleet``, each stage timed in ``stages``: per query
        (:mod:`service.batch_items`), or with ``atomic`` all or nothing (a 422 for any bad query)."""
        answers, errors, content = await self.work.run(self._batch, body, fleet, stages, atomic)
        if errors:
            answered = [i for i in range(len(answers.state)) if i not in errors]
            self.metrics.observe_answers([answers.state[i] for i in answered], [answers.level[i] for i in answered])
            self.metrics.observe_item_errors(error["error"]["code"] for error in errors.values())
        else:
            self.metrics.observe_answers(answers.state, answers.level)
        return content

    def _one(self, body: bytes, fleet: str) -> EncodedAnswers:
        """Decode and answer one query (on the work thread)."""
        return self.service.answer([decode(body, DecodedQuery, QUERY_ADAPTER)], loc=("body",), fleet=fleet)

    def _batch(self, body: bytes, fleet: str, stages: Stages, atomic: bool) -> tuple[EncodedAnswers, ItemErrors, bytes]:
        """Decode, answer and encode a batch (on the work thread); the error entries of the queries not answered."""
        with stages("decode"):
            if atomic:
                queries, errors = decode(body, DecodedBatch, BATCH_ADAPTER).queries, None
            else:
                queries, errors = decode_items(body)
        answers = self.service.answer(queries, fleet=fleet, stages=stages, errors=errors)
        with stages("encode"):
            for index, error in (errors or {}).items():
                answers.documents[index] = error
            return answers, errors or {}, answers.batch_json()
