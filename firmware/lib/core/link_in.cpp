// Frames from the host: HELLO, HEARTBEAT, FIX (into the estimator), PATH (assembled from its
// chunks, acknowledged one by one, replacing the path held only when complete), START, STOP and
// CONFIG. A FIX costs the Uno about 1.8 ms: at most one is taken a step (see Rover::step).
#include "rover.h"

#include "float_ops.h"

namespace rovernav {
namespace core {

// The bytes received: frames decoded, checked for their signature (frame_auth.h), handled.
// A tag is a step's heavy job (0.3-0.8 ms on the Uno): after one, the rest of the bytes wait
// for the next step (the shell gives them again); a step kept for a put-off job, or with a
// sonar result, takes no signed frame at all. A rover with no key computes no tag and takes
// everything at once.
ROVERNAV_NOINLINE uint8_t Rover::take_frames(const Inputs& in, uint32_t now) {
  if (fix_verified_) {
    // The FIX whose tag the last step checked (still in the decoder: nothing is pushed until it
    // is taken) is this step's job, unless a sonar result was put off too: the sweep waits for
    // that, the estimator can wait a step more. The FIX is 10-20 ms older than its age says.
    if (sonar_held_ || in.sonar_valid) return 0;
    fix_verified_ = false;
    step_work_ = static_cast<uint8_t>(step_work_ & ~kWorkReserved);
    handle_frame(decoder_.frame(), now, static_cast<uint16_t>(now - last_rx_ms_));
    return 0;
  }
  // A step kept for a put-off job, or one with a sonar result to take in (the sweep's pace),
  // leaves the signed frames to the next.
  if (auth_.keyed() && ((step_work_ & kWorkReserved) || in.sonar_valid)) return 0;
  uint8_t used = 0;
  while (used < in.rx_len) {
    if (!decoder_.push(in.rx[used++])) continue;
    const AuthResult r = auth_.check(decoder_.frame());
    if (r == AuthResult::Accepted || r == AuthResult::AcceptedAfterTag) {
      last_rx_ms_ = now;   // only frames we take keep the link alive (a forger's do not)
      if (r == AuthResult::AcceptedAfterTag && decoder_.frame().msg_id == msg::Fix::kId) {
        fix_verified_ = put_off_ = true;   // a tag and an estimator update do not fit one step
      } else {
        handle_frame(decoder_.frame(), now, 0);
      }
    }
    if (r == AuthResult::AcceptedAfterTag || r == AuthResult::RefusedAfterTag) {
      step_work_ = static_cast<uint8_t>(step_work_ | kWorkTag);
      break;
    }
  }
  return used;
}

ROVERNAV_NOINLINE void Rover::handle_frame(const Frame& f, uint32_t now, uint16_t late_ms) {
  // The decoder has checked the payload's length against the id's: one copy decodes any message.
  union {
    msg::Hello hello;
    msg::Heartbeat heartbeat;
    msg::Fix fix;
    msg::Path path;
    msg::Start start;
    msg::Stop stop;
    msg::Config config;
    msg::Provision provision;
  } m;
  wire::copy(&m, f.payload, f.payload_len < sizeof m ? f.payload_len : static_cast<uint8_t>(sizeof m));
  switch (f.msg_id) {
    case msg::Hello::kId:
      if (m.hello.role == static_cast<uint8_t>(Role::Host)) {
        schema_ok_ = m.hello.schema_hash == kSchemaHash;
        send_hello();
      }
      break;
    case msg::Heartbeat::kId:
      camera_ = m.heartbeat.camera;
      host_knows_ = m.heartbeat.scan_heard == scan_id_ && m.heartbeat.path_id == path_id_;
      break;
    case msg::Fix::kId:
      m.fix.age_ms = static_cast<uint16_t>(m.fix.age_ms + late_ms);
      on_fix(m.fix, now);
      break;
    case msg::Path::kId:
      on_path(m.path, f.seq);
      break;
    case msg::Start::kId:
      on_start(m.start, f.seq);
      break;
    case msg::Stop::kId:
      on_stop(m.stop, f.seq);
      break;
    case msg::Config::kId:
      on_config(m.config, f.seq);
      break;
    case msg::Provision::kId:
      // Signed and taken: its tag passed under the key held (a rover with no key takes no signed frame).
      on_provision(m.provision, f.seq, now, f.signed_len != 0);
      break;
    default:
      break;  // a rover-to-host message echoed back: valid, not for us
  }
}

// Out of line: pasted into handle_frame, the estimator update's floats joined its 37-byte
// message union on the stack, past the AVR's short (Y+63) offsets: a pair of pointer moves
// round every spill.
ROVERNAV_NOINLINE void Rover::on_fix(const msg::Fix& m, uint32_t now) {
  if (step_work_ & (kWorkFix | kWorkReserved)) return;   // one FIX a step, none in a reserved one (see step())
  step_work_ = static_cast<uint8_t>(step_work_ | kWorkFix);
  PoseFix fix;
  fix.x_mm = m.x_mm;
  fix.y_mm = m.y_mm;
  fix.heading_cdeg = m.heading_cdeg;
  fix.sd_mm = m.sd_mm;
  fix.taken_ms = now - m.age_ms - kLinkDelayMs;
  const FixResult r = est_.update(fix, now);
  if (r == FixResult::Rejected) return;
  last_fix_ms_ = now;
  had_fix_ = true;
  if (dead_reckoning_) {
    dead_reckoning_ = false;
    send_event(EventKind::CameraBack, est_.last_innovation_mm());
  }
  dr_distance_mm_ = 0.0f;
  calibrate_speed(m, now, r);
}

void Rover::on_path(const msg::Path& m, uint8_t seq) {
  const uint8_t id = msg::Path::kId;
  if (state_ == RoverState::Planning) no_detour();   // the staging buffer is the planner's scratch; the host's path will do
  // A repeat (its ACK was lost and the host sent it again): ACK again. While staging, of the
  // chunk just taken; once the path is held whole, of any of its chunks (staging it anew would
  // leave a part-staged copy that keeps the rover from planning its own detours).
  if (m.path_id == stage_id_ &&
      (staging_ ? m.first_index + 1 == last_chunk_ : (path_id_ == m.path_id && path_len_ == m.total))) {
    ack(id, seq);
    return;
  }
  if (m.total > kMaxWaypoints) return nack(id, seq, NackReason::TooManyWaypoints, kMaxWaypoints);
  if (m.total == 0) return nack(id, seq, NackReason::BadValue, 2);
  if (m.count == 0 || m.count > kWaypointsPerChunk || m.first_index + m.count > m.total)
    return nack(id, seq, NackReason::BadValue, 4);
  for (uint8_t i = 0; i < m.count; ++i) {
    if (m.x_mm[i] < 0 || m.y_mm[i] < 0) return nack(id, seq, NackReason::BadValue, static_cast<uint16_t>(m.first_index + i));
  }
  const bool continues = staging_ && m.path_id == stage_id_ && m.total == stage_total_;
  if (m.first_index == 0 && !continues) {
    staging_ = true;
    stage_id_ = m.path_id;
    stage_total_ = m.total;
    stage_count_ = 0;
  } else if (!continues || m.first_index != stage_count_) {
    return nack(id, seq, NackReason::OutOfOrder, continues ? stage_count_ : 0);
  }
  for (uint8_t i = 0; i < m.count; ++i) {
    stage_[m.first_index + i].x_mm = m.x_mm[i];
    stage_[m.first_index + i].y_mm = m.y_mm[i];
  }
  stage_count_ = static_cast<uint8_t>(stage_count_ + m.count);
  last_chunk_ = static_cast<uint8_t>(m.first_index + 1);
  ack(id, seq);
  if (stage_count_ < stage_total_) return;

  // Complete: it replaces the path held, and a running mission follows it at once (from the
  // nearest leg's end, chosen in a step with time for it).
  step_work_ = static_cast<uint8_t>(step_work_ | kWorkOther);
  staging_ = false;
  for (uint8_t i = 0; i < stage_total_; ++i) path_[i] = stage_[i];
  path_len_ = stage_total_;
  path_id_ = stage_id_;
  detour_n_ = detour_i_ = 0;  // the host's path replaces the rover's own detour
  trusted_host_ = host_knows_ = false;
  // The host's map holds something within reach of the corners where the rover stands, and no
  // room straight ahead: its next turn on the spot backs out first (a rotation under way is
  // checked again).
  back_out_ = m.back_out;
  if (back_out_ != 0) rotate_checked_ = false;
  send_event(EventKind::PathAccepted, path_id_);
  if (mission_ && est_.initialised()) {
    pick_target_ = true;
    // A rover its reflex stopped on the host's last path looks before it takes a new one: a host
    // that never heard the sweep (its reports lost on a lossy radio) sends the same way again.
    // The sweep's check (replan_locally) then finds its own way round, or holds it Blocked.
    // A rover Blocked stays so until the new leg is seen to clear what the sweep saw (mode_blocked).
    if (reflex_after_trust_) {
      start_sweep();
    } else if (state_ == RoverState::Drive || state_ == RoverState::Rotate) {
      enter(RoverState::Rotate);
    }
  }
}

void Rover::on_start(const msg::Start& m, uint8_t seq) {
  const uint8_t id = msg::Start::kId;
  if (!schema_ok_) return nack(id, seq, NackReason::SchemaMismatch, 0);
  if (fault_ != FaultCode::None) return nack(id, seq, NackReason::Faulted, static_cast<uint16_t>(fault_));
  if (path_len_ == 0) return nack(id, seq, NackReason::NoPath, 0);
  if (m.path_id != path_id_) return nack(id, seq, NackReason::PathIdMismatch, path_id_);
  if (!est_.initialised()) return nack(id, seq, NackReason::NoFix, 0);
  ack(id, seq);
  if (mission_) return;  // already running this path
  mission_ = true;
  wp_ = 0;
  pick_target_ = true;
  local_.clear();   // the rover may have been carried since: what it remembers is of elsewhere
  // sweep_distance_mm_ carries over: "every 0.3 m travelled" counts across missions too.
  // Look before the first turn: something beside the rover would be hit by its corners as it turns.
  if (params_.sweep_at_start()) {
    start_sweep();
  } else {
    enter(RoverState::Rotate);
  }
}

void Rover::on_stop(const msg::Stop& m, uint8_t seq) {
  ack(msg::Stop::kId, seq);
  stop_sweep();
  if (state_ != RoverState::Fault) enter(RoverState::Idle);
  mission_ = false;
  send_event(EventKind::Stopped, m.reason);
}

void Rover::on_config(const msg::Config& m, uint8_t seq) {
  switch (params_.set(m.param, m.value)) {
    case SetResult::Ok: return ack(msg::Config::kId, seq);
    case SetResult::UnknownParam: return nack(msg::Config::kId, seq, NackReason::UnknownParam, m.param);
    case SetResult::OutOfRange: return nack(msg::Config::kId, seq, NackReason::ParamOutOfRange, m.param);
  }
}

// PROVISION. A rover with a key changes it (or forgets it) only with its owner's consent: the
// frame signed with that key (its tag checked: at any time), or the consent pin held to GND at
// the reset (kSignConsentResetBit in the reset cause the shell gave begin()); else NACK
// needs_consent, whatever the reset was: a power-on, a brown-out or the watchdog's opens no
// door, and behind the Uno's optiboot the sketch cannot tell them from the reset button anyway.
// A rover with no key takes it unsigned (first use). Unsigned, only within kSignProvisionWindowMs
// of a reset: the radio cannot reset the rover; a person can (the reset button, or opening the
// USB port, which resets the Uno through DTR: `rovernav provision`). The new key signs the ACK.
void Rover::on_provision(const msg::Provision& m, uint8_t seq, uint32_t now, bool verified) {
  const uint8_t id = msg::Provision::kId;
  if (!verified) {
    if (auth_.keyed() && !(reset_cause_ & kSignConsentResetBit)) return nack(id, seq, NackReason::NeedsConsent, kSignConsentPin);
    const uint32_t since_ms = now - boot_ms_;
    if (since_ms > kSignProvisionWindowMs) {
      const uint32_t s = since_ms / 1000;
      return nack(id, seq, NackReason::NotNow, s > 0xFFFF ? 0xFFFF : static_cast<uint16_t>(s));
    }
  }
  if (m.erase > 1) return nack(id, seq, NackReason::BadValue, 2);
  const Counter48 tx = auth_.tx_last(), rx = auth_.rx_last();
  auth_.begin(m.erase ? nullptr : m.key);
  auth_.resume(tx, rx);   // past every counter of the old key too
  key_change_ = m.erase ? kKeyErase & 3u : kKeyStore & 3u;
  persisted_once_ = false;  // the counters are stored again with the key
  ack(id, seq);
  send_event(EventKind::KeyStored, m.erase ? 0 : 1);
}

}  // namespace core
}  // namespace rovernav
