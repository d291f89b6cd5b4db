"""The request tracker the mission and Link.request share: matching answers, resends, limits."""

from __future__ import annotations

import pytest

from rovernav.link import messages_gen as mg
from rovernav.link.requests import RequestTracker


def test_a_late_answer_to_an_earlier_attempt_answers_the_request():
    t = RequestTracker(resend_s=0.4, max_tries=3)
    p = t.sent(mg.Start(path_id=7), seq=10, now_s=0.0)
    t.resent(p, seq=11, now_s=0.4)
    assert t.answer(mg.Ack(msg_id=mg.Start.ID, seq=10)) is p
    assert not t and t.answer(mg.Ack(msg_id=mg.Start.ID, seq=11)) is None  # the duplicate answers nothing


def test_an_answer_for_another_message_id_or_seq_does_not_match():
    t = RequestTracker(resend_s=0.4, max_tries=3)
    t.sent(mg.Start(path_id=7), seq=10, now_s=0.0)
    assert t.answer(mg.Ack(msg_id=mg.Config.ID, seq=10)) is None
    assert t.answer(mg.Nack(msg_id=mg.Start.ID, seq=9, reason=1, detail=0)) is None
    assert len(t) == 1


def test_requests_fall_due_after_resend_s_and_are_exhausted_after_max_tries():
    t = RequestTracker(resend_s=0.5, max_tries=2)
    p = t.sent(mg.Config(param=1, value=2), seq=1, now_s=0.0)
    assert t.due(0.49) == [] and t.due(0.5) == [p]
    assert not t.exhausted(p)
    t.resent(p, seq=2, now_s=0.5, count=False)  # a silent rover: not counted
    assert p.tries == 1 and not t.exhausted(p)
    t.resent(p, seq=3, now_s=1.0)
    assert p.tries == 2 and t.exhausted(p) and t.due(1.2) == []


def test_a_wrapped_sequence_number_belongs_to_the_newest_request():
    t = RequestTracker(resend_s=0.4, max_tries=3)
    old = t.sent(mg.Config(param=1, value=1), seq=5, now_s=0.0)
    new = t.sent(mg.Config(param=2, value=2), seq=5, now_s=1.0)  # 256 frames later, seq 5 again
    assert t.answer(mg.Ack(msg_id=mg.Config.ID, seq=5)) is new
    assert list(t) == [old] and old.seqs == []


def test_bad_limits_are_refused():
    with pytest.raises(ValueError, match="resend_s"):
        RequestTracker(resend_s=0, max_tries=1)
    with pytest.raises(ValueError, match="max_tries"):
        RequestTracker(resend_s=1, max_tries=0)
