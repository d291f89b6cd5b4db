"""Requests that the rover answers with ACK or NACK: which are unanswered, which answer is whose,
and when to send one again. Shared by the blocking `Link.request` and the non-blocking mission.

A request keeps every sequence number it was sent under, so a late answer to an earlier
attempt still answers it. The tracker never sends anything itself and reads no clock: the
caller says what it sent and when (`sent`, `resent`), hands it each ACK/NACK (`answer`) and
asks which requests are due again (`due`).
"""

from __future__ import annotations

import dataclasses

from ..validate import check_number
from .messages_gen import Ack, Nack
from .schema import Message


@dataclasses.dataclass
class Pending:
    """One request awaiting its answer."""

    message: Message
    seqs: list[int]  # every sequence number it went out under, oldest first
    first_sent_s: float
    last_sent_s: float
    tries: int = 1  # attempts counted against the limit (see RequestTracker.resent)


class RequestTracker:
    """Unanswered requests, by sequence number.

    resend_s: an unanswered request is due again this long [s] after it was last sent.
    max_tries: attempts a request may have before `due` reports it as exhausted.
    """

    def __init__(self, resend_s: float, max_tries: int) -> None:
        self.resend_s = check_number("resend_s (seconds)", resend_s, 0.0, None, lo_open=True)
        self.max_tries = check_number("max_tries", max_tries, 1, None, integer=True)
        self._by_seq: dict[int, Pending] = {}
        self._pending: list[Pending] = []

    def __len__(self) -> int:
        return len(self._pending)

    def __bool__(self) -> bool:
        return bool(self._pending)

    def __iter__(self):
        return iter(list(self._pending))

    def sent(self, message: Message, seq: int, now_s: float) -> Pending:
        """A new request went out under `seq` at `now_s`."""
        p = Pending(message, [seq], now_s, now_s)
        self._pending.append(p)
        self._remember(seq, p)
        return p

    def resent(self, pending: Pending, seq: int, now_s: float, count: bool = True) -> None:
        """`pending` went out again under `seq`; `count=False` does not count the attempt
        (the mission's rule while the rover is silent: it is carrying on alone). A request
        keeps each sequence number once, so its list never passes 256 however often it is
        re-sent."""
        if seq in pending.seqs:
            pending.seqs.remove(seq)
        pending.seqs.append(seq)
        pending.last_sent_s = now_s
        if count:
            pending.tries += 1
        self._remember(seq, pending)

    def answer(self, reply: Message) -> Pending | None:
        """The request an ACK or NACK answers (removed from the tracker), or None when it
        answers nothing outstanding (a duplicate, or a request already given up)."""
        if not isinstance(reply, (Ack, Nack)):
            return None
        p = self._by_seq.get(reply.seq)
        if p is None or p.message.ID != reply.msg_id:
            return None
        self._forget(p)
        return p

    def matches(self, reply: Message) -> bool:
        """Whether `reply` answers an outstanding request (without removing it)."""
        if not isinstance(reply, (Ack, Nack)):
            return False
        p = self._by_seq.get(reply.seq)
        return p is not None and p.message.ID == reply.msg_id

    def again(self, pending: Pending) -> None:
        """An answered request is outstanding again (it was refused for a reason that passes:
        the rover did not yet know this host, or had no fix): due resend_s after its last
        attempt, keeping its attempts."""
        if pending not in self._pending:
            self._pending.append(pending)
            for s in pending.seqs:
                self._remember(s, pending)

    def due(self, now_s: float) -> list[Pending]:
        """Requests whose resend time has come, oldest first."""
        return [p for p in self._pending if now_s - p.last_sent_s >= self.resend_s]

    def exhausted(self, pending: Pending) -> bool:
        """Whether `pending` has had all its attempts."""
        return pending.tries >= self.max_tries

    def drop(self, pending: Pending) -> None:
        """Stop waiting for `pending`."""
        self._forget(pending)

    def clear(self) -> None:
        self._by_seq.clear()
        self._pending.clear()

    def _remember(self, seq: int, p: Pending) -> None:
        old = self._by_seq.get(seq)
        if old is not None and old is not p:
            # The 8-bit sequence number came round while an old attempt of another request was
            # still remembered: that attempt can no longer be told apart, so forget it.
            old.seqs = [s for s in old.seqs if s != seq]
        self._by_seq[seq] = p

    def _forget(self, p: Pending) -> None:
        for s in p.seqs:
            if self._by_seq.get(s) is p:
                del self._by_seq[s]
        if p in self._pending:
            self._pending.remove(p)
