"""Warnings over HTTP: a query or a batch decoded, answered on the work thread, encoded, and counted.

:class:`Answering` is what the warning routes depend on (:mod:`service.deps`): one dependency
holding the service, the work thread and the metrics, since each dependency FastAPI resolves costs
the single query, the hottest route, its own share of time.
"""

from __future__ import annotations

from dataclasses import dataclass

from .answers import EncodedAnswers, WarningService
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

    async def batch(self, body: bytes, fleet: str, stages: Stages) -> bytes:
        """The JSON answers to the body of a batch of ``fleet``, each stage timed in ``stages``."""
        answers, content = await self.work.run(self._batch, body, fleet, stages)
        self.metrics.observe_answers(answers.state, answers.level)
        return content

    def _one(self, body: bytes, fleet: str) -> EncodedAnswers:
        """Decode and answer one query (on the work thread)."""
        return self.service.answer([decode(body, DecodedQuery, QUERY_ADAPTER)], loc=("body",), fleet=fleet)

    def _batch(self, body: bytes, fleet: str, stages: Stages) -> tuple[EncodedAnswers, bytes]:
        """Decode, answer and encode a batch (on the work thread)."""
        with stages("decode"):
            queries = decode(body, DecodedBatch, BATCH_ADAPTER).queries
        answers = self.service.answer(queries, fleet=fleet, stages=stages)
        with stages("encode"):
            return answers, answers.batch_json()
