"""A path sent to the rover chunk by chunk, made for a radio that loses frames.

The rover takes a path's PATH chunks in order only, ACKs each one it takes, ACKs again a repeat
of the chunk it took last, and NACKs any other chunk `out_of_order`, naming the first waypoint it
expects next (0 when it holds no part of this path). So an ACK of a chunk says the rover holds
every chunk up to it, and an `out_of_order` NACK says exactly where it stopped. The upload:

  * sends every chunk at once (a 32-waypoint path is four frames, 0.03 s of the line);
  * takes each answer for what it says of the rover's progress: an ACK of chunk k marks chunks
    0..k taken; a NACK naming first waypoint d marks every chunk before d taken and makes the
    chunks from d on due again at once, in order (selective retransmission: what the rover holds
    is never sent again, and the load resumes where it stopped rather than from the start);
  * re-sends, in order, any chunk still unanswered `resend_s` after it last went out;
  * counts attempts per chunk (`tries`) so that its owner can give up on a link that answers
    nothing (see `exhausted`), while a NACK that moves the load on costs no attempt.

A NACK that answers an attempt older than the last re-send of the chunk it names says nothing
new (that chunk has gone out again since), so it does not send the rest once more: a lost chunk
in a burst of four costs the chunks behind it one re-send each, not one per NACK.

It never sends anything and reads no clock: the caller sends what `due()` returns and tells it
under which sequence number and when (`sent`), and hands it each ACK or NACK (`answer`). Shared
by the mission and `rovernav link-check --soak`.
"""

from __future__ import annotations

import dataclasses
import enum

from . import messages_gen as mg

#: Chunks go out one at a time, this far apart [s] at least: the rover checks one signed frame a
#: 10 ms step, so four 56-byte chunks at once, with the FIXes among them, would overrun its
#: 128-byte serial buffer (`rovernav link-check --soak` saw 0.3 % of frames lost so on a clean line).
CHUNK_SPACING_S = 0.03


class Answer(enum.Enum):
    """What an ACK or NACK meant to the upload."""

    NOT_OURS = "not_ours"  # answers no chunk of this upload
    TAKEN = "taken"  # an ACK: the rover holds the chunks up to this one
    RESUME = "resume"  # a NACK out_of_order: re-sending from where the rover stopped
    REFUSED = "refused"  # a NACK for another reason: the path itself is wrong


@dataclasses.dataclass
class _Chunk:
    message: mg.Path
    taken: bool = False
    sent_s: float | None = None  # when it last went out (None: due now)
    tries: int = 0  # attempts that went unanswered so far
    sends: int = 0  # times it went out
    resumed: bool = False  # made due by a NACK (not by its resend time) ...
    sent_by_nack: bool = False  # ... and its last attempt was that one


def path_chunks(path_id: int, waypoints_mm: list[tuple[int, int]], back_out: int = 0) -> list[mg.Path]:
    """The PATH messages that carry `waypoints_mm` (at most MAX_WAYPOINTS) under `path_id`; each
    carries `back_out` (1: back out before the first turn; the rover reads it from the chunk that
    completes the path)."""
    if not 1 <= len(waypoints_mm) <= mg.MAX_WAYPOINTS:
        raise ValueError(f"a path holds 1 to {mg.MAX_WAYPOINTS} waypoints, not {len(waypoints_mm)}")
    if back_out not in (0, 1):
        raise ValueError(f"back_out must be 0 or 1, not {back_out!r}")
    n = mg.WAYPOINTS_PER_CHUNK
    out = []
    for first in range(0, len(waypoints_mm), n):
        chunk = waypoints_mm[first : first + n]
        xs = tuple(x for x, _ in chunk) + (0,) * (n - len(chunk))
        ys = tuple(y for _, y in chunk) + (0,) * (n - len(chunk))
        out.append(
            mg.Path(
                path_id=path_id,
                total=len(waypoints_mm),
                first_index=first,
                count=len(chunk),
                back_out=back_out,
                x_mm=xs,
                y_mm=ys,
            )
        )
    return out


class PathUpload:
    """One path on its way to the rover. See the module docstring."""

    def __init__(self, path_id: int, waypoints_mm: list[tuple[int, int]], resend_s: float, back_out: int = 0) -> None:
        if not resend_s > 0:
            raise ValueError(f"resend_s must be > 0 s, not {resend_s!r}")
        self.path_id = path_id
        self.resend_s = resend_s
        self._chunks = [_Chunk(m) for m in path_chunks(path_id, waypoints_mm, back_out)]
        self._attempts: dict[int, tuple[int, float]] = {}  # seq -> (chunk index, when sent)
        self.frames_sent = 0
        self.frames_resent = 0
        self.refusal: mg.Nack | None = None

    @property
    def chunks(self) -> int:
        return len(self._chunks)

    @property
    def complete(self) -> bool:
        """Every chunk is taken: the rover holds the whole path."""
        return all(c.taken for c in self._chunks)

    @property
    def taken(self) -> int:
        """Chunks the rover is known to hold."""
        return sum(c.taken for c in self._chunks)

    def tries(self) -> int:
        """The most unanswered attempts any chunk still to be taken has had."""
        return max((c.tries for c in self._chunks if not c.taken), default=0)

    def due(self, now_s: float) -> list[mg.Path]:
        """The chunks to send now, in order: those never sent, those made due by a NACK, and those
        unanswered for resend_s."""
        return [
            c.message for c in self._chunks if not c.taken and (c.sent_s is None or now_s - c.sent_s >= self.resend_s)
        ]

    def sent(self, message: mg.Path, seq: int, now_s: float, count: bool = True) -> None:
        """`message` (one of ours, from `due`) went out under `seq` at `now_s`; `count=False` does
        not count the attempt (its owner's rule while the rover is silent)."""
        index = message.first_index // mg.WAYPOINTS_PER_CHUNK
        chunk = self._chunks[index]
        if chunk.sends:
            self.frames_resent += 1
        chunk.sends += 1
        chunk.sent_by_nack, chunk.resumed = chunk.resumed, False
        chunk.sent_s = now_s
        chunk.tries += 1 if count else 0
        self.frames_sent += 1
        # One sequence number names one attempt; a number that comes round again names the new one.
        self._attempts[seq] = (index, now_s)

    def mark_complete(self) -> None:
        """The rover said it holds the whole path (its PATH_ACCEPTED event)."""
        for c in self._chunks:
            c.taken = True

    def answer(self, reply) -> Answer:
        """Take an ACK or NACK: what it says of the rover's progress (see the module docstring)."""
        if not isinstance(reply, (mg.Ack, mg.Nack)) or reply.msg_id != mg.Path.ID:
            return Answer.NOT_OURS
        attempt = self._attempts.get(reply.seq)
        if attempt is None:
            return Answer.NOT_OURS
        index, sent_s = attempt
        if isinstance(reply, mg.Ack):
            for c in self._chunks[: index + 1]:
                c.taken = True
            return Answer.TAKEN
        if reply.reason != mg.NackReason.OUT_OF_ORDER:
            self.refusal = reply
            return Answer.REFUSED
        expected = reply.detail // mg.WAYPOINTS_PER_CHUNK if reply.detail % mg.WAYPOINTS_PER_CHUNK == 0 else None
        if expected is None or expected > len(self._chunks):
            self.refusal = reply  # a place no chunk of ours starts at: not this path's upload
            return Answer.REFUSED
        for i, c in enumerate(self._chunks):
            if i < expected:
                c.taken = True
            elif expected == 0:
                c.taken = False  # the rover holds none of it (it restarted, or took another path)
        if expected < len(self._chunks):
            head = self._chunks[expected]
            if (head.sent_s is None or head.sent_s <= sent_s) and not head.sent_by_nack:
                # The chunk the rover waits for went out no later than the refused one, and was
                # lost: the rest from it on, at once, in order. The chunks behind it were
                # answered (refused for coming early), so their attempts do not count. Once
                # only: if that attempt is lost too, the next waits for its resend time, so a
                # chunk lost again and again goes out at most twice per resend_s.
                for c in self._chunks[expected:]:
                    if not c.taken:
                        c.sent_s, c.resumed = None, True
                        if c is not head:
                            c.tries = max(0, c.tries - 1)
        return Answer.RESUME
