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
// everything at once. Left to LTO, which pastes it into step() (its one caller): 28 bytes of
// flash less than the call with avr-gcc 7.3, the same with 5.4, and step()'s frame no larger.
uint8_t Rover::take_frames(const Inputs& in, uint32_t now) {
  if (link_.fix_verified) {
    // The FIX whose tag the last step checked (still in the decoder: nothing is pushed until it
    // is taken) is this step's job, unless a sonar result was put off too: the sweep waits for
    // that, the estimator can wait a step more. The FIX is 10-20 ms older than its age says.
    if (step_.sonar_held || in.sonar_valid) return 0;
    link_.fix_verified = false;
    step_.spend_reserve();   // on the job it was kept for
    handle_frame(decoder_.frame(), now, static_cast<uint16_t>(now - failsafe_.last_rx_ms));
    return 0;
  }
  // A step kept for a put-off job, or one with a sonar result to take in (the sweep's pace),
  // leaves the signed frames to the next.
  if (link_.auth.keyed() && ((step_.work & kWorkReserved) || in.sonar_valid)) return 0;
  uint8_t used = 0;
  while (used < in.rx_len) {
    if (!decoder_.push(in.rx[used++], link_.auth.address_bits())) continue;   // another rover's: dropped there
    const AuthResult r = link_.auth.check(decoder_.frame());
    if (r == AuthResult::Accepted || r == AuthResult::AcceptedAfterTag) {
      failsafe_.heard(now);   // only frames we take keep the link alive (a forger's do not)
      // The host's poll, the last frame of its slot (a FIX, else a HEARTBEAT), opens a fleet
      // rover's grant to speak, in this step only (rover.cpp): the host's frames are off the air.
      const uint8_t id = decoder_.frame().msg_id;
      if (id == msg::Fix::kId || id == msg::Heartbeat::kId) link_.grant_opens();
      if (r == AuthResult::AcceptedAfterTag && decoder_.frame().msg_id == msg::Fix::kId) {
        link_.fix_verified = true;   // a tag and an estimator update do not fit one step
        step_.defer();
      } else {
        handle_frame(decoder_.frame(), now, 0);
      }
    }
    if (r == AuthResult::AcceptedAfterTag || r == AuthResult::RefusedAfterTag) {
      step_.did(kWorkTag);
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
        link_.schema_ok = m.hello.schema_hash == kSchemaHash;
        send_hello();
      }
      break;
    case msg::Heartbeat::kId:
      link_.camera = m.heartbeat.camera;
      detour_.hear_host(m.heartbeat.scan_heard == sonar_.scan_id && m.heartbeat.path_id == mission_.path_id);
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

// Left to LTO, which pastes it into handle_frame: since the estimator's correction went out of
// line (Estimator::correct), the pasted copy no longer spills past the AVR's short (Y+63) stack
// offsets at every access, and it saves 36 bytes of flash with avr-gcc 7.3 and 22 with 5.4 over
// the call (handle_frame's frame grows from 54 to 68 bytes, less than on_fix's own 28 and its
// saved registers: the FIX's stack is no deeper).
void Rover::on_fix(const msg::Fix& m, uint32_t now) {
  if (step_.work & (kWorkFix | kWorkReserved)) return;   // one FIX a step, none in a reserved one (see step())
  step_.did(kWorkFix);
  PoseFix fix;
  fix.x_mm = m.x_mm;
  fix.y_mm = m.y_mm;
  fix.heading_cdeg = m.heading_cdeg;
  fix.sd_mm = m.sd_mm;
  fix.taken_ms = now - m.age_ms - kLinkDelayMs;
  const FixResult r = odometry_.est.update(fix, now);
  if (r == FixResult::Rejected) return;
  if (failsafe_.took_fix(now)) send_event(EventKind::CameraBack, odometry_.est.last_innovation_mm());
  odometry_.restart_dr();
  calibrate_speed(m, now, r);
}

void Rover::on_path(const msg::Path& m, uint8_t seq) {
  const uint8_t id = msg::Path::kId;
  if (step_.state == RoverState::Planning) no_detour();   // the staging buffer is the planner's scratch; the host's path will do
  // A repeat (its ACK was lost and the host sent it again): ACK again. While staging, of the
  // chunk just taken; once the path is held whole, of any of its chunks (staging it anew would
  // leave a part-staged copy that keeps the rover from planning its own detours).
  if (m.path_id == link_.stage_id &&
      (link_.staging ? m.first_index + 1 == link_.last_chunk : (mission_.path_id == m.path_id && mission_.path_len == m.total))) {
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
  const bool continues = link_.staging && m.path_id == link_.stage_id && m.total == link_.stage_total;
  if (m.first_index == 0 && !continues) {
    link_.staging = true;
    link_.stage_id = m.path_id;
    link_.stage_total = m.total;
    link_.stage_count = 0;
  } else if (!continues || m.first_index != link_.stage_count) {
    return nack(id, seq, NackReason::OutOfOrder, continues ? link_.stage_count : 0);
  }
  for (uint8_t i = 0; i < m.count; ++i) {
    link_.stage[m.first_index + i].x_mm = m.x_mm[i];
    link_.stage[m.first_index + i].y_mm = m.y_mm[i];
  }
  link_.stage_count = static_cast<uint8_t>(link_.stage_count + m.count);
  link_.last_chunk = static_cast<uint8_t>(m.first_index + 1);
  ack(id, seq);
  if (link_.stage_count < link_.stage_total) return;

  // Complete: it replaces the path held, and a running mission follows it at once (from the
  // nearest leg's end, chosen in a step with time for it).
  step_.did(kWorkOther);
  link_.staging = false;
  for (uint8_t i = 0; i < link_.stage_total; ++i) mission_.path[i] = link_.stage[i];
  mission_.path_len = link_.stage_total;
  mission_.path_id = link_.stage_id;
  detour_.take_host_path();  // the host's path replaces the rover's own detour
  // The host's map holds something within reach of the corners where the rover stands, and no
  // room straight ahead: its next turn on the spot backs out first (a rotation under way is
  // checked again).
  motion_.host_back_out(m.back_out);
  send_event(EventKind::PathAccepted, mission_.path_id);
  if (mission_.active && odometry_.est.initialised()) {
    mission_.pick_target = true;
    // A rover its reflex stopped on the host's last path looks before it takes a new one: a host
    // that never heard the sweep (its reports lost on a lossy radio) sends the same way again.
    // The sweep's check (replan_locally) then finds its own way round, or holds it Blocked.
    // A rover Blocked stays so until the new leg is seen to clear what the sweep saw (mode_blocked).
    if (detour_.reflex_after_trust) {
      start_sweep();
    } else if (step_.state == RoverState::Drive || step_.state == RoverState::Rotate) {
      enter(RoverState::Rotate);
    }
  }
}

void Rover::on_start(const msg::Start& m, uint8_t seq) {
  const uint8_t id = msg::Start::kId;
  if (!link_.schema_ok) return nack(id, seq, NackReason::SchemaMismatch, 0);
  if (failsafe_.fault != FaultCode::None) return nack(id, seq, NackReason::Faulted, static_cast<uint16_t>(failsafe_.fault));
  if (mission_.path_len == 0) return nack(id, seq, NackReason::NoPath, 0);
  if (m.path_id != mission_.path_id) return nack(id, seq, NackReason::PathIdMismatch, mission_.path_id);
  if (!odometry_.est.initialised()) return nack(id, seq, NackReason::NoFix, 0);
  ack(id, seq);
  if (mission_.active) return;  // already running this path
  mission_.active = true;
  mission_.wp = 0;
  mission_.pick_target = true;
  // sonar_.sweep_distance_mm carries over: "every 0.3 m travelled" counts across missions too.
  // Going on from where the host stopped it, standing still since (the host's camera saw it):
  // what it remembers is of here, and it swept on this leg. Else it may have been carried since:
  // what it remembers is of elsewhere, and it looks before the first turn (something beside the
  // rover would be hit by its corners as it turns).
  if (m.resume == 0) {
    detour_.forget();
    if (params_.sweep_at_start()) return start_sweep();
  }
  enter(RoverState::Rotate);
}

void Rover::on_stop(const msg::Stop& m, uint8_t seq) {
  ack(msg::Stop::kId, seq);
  stop_sweep();
  if (step_.state != RoverState::Fault) enter(RoverState::Idle);
  mission_.active = false;
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
// USB port, which resets the Uno through DTR: `rovernav provision`). The new key signs the ACK,
// which goes out at the address of the new fleet id ([fleet]; stored with the key, erased or not).
void Rover::on_provision(const msg::Provision& m, uint8_t seq, uint32_t now, bool verified) {
  const uint8_t id = msg::Provision::kId;
  if (!verified) {
    if (link_.auth.keyed() && !(link_.reset_cause & kSignConsentResetBit)) return nack(id, seq, NackReason::NeedsConsent, kSignConsentPin);
    const uint32_t since_ms = now - link_.boot_ms;
    if (since_ms > kSignProvisionWindowMs) {
      const uint32_t s = since_ms / 1000;
      return nack(id, seq, NackReason::NotNow, s > 0xFFFF ? 0xFFFF : static_cast<uint16_t>(s));
    }
  }
  if (m.erase > 1) return nack(id, seq, NackReason::BadValue, 2);
  if (m.fleet_id > kMaxRovers) return nack(id, seq, NackReason::BadValue, 3);
  const Counter48 tx = link_.auth.tx_last(), rx = link_.auth.rx_last();
  link_.auth.begin(m.erase ? nullptr : m.key);
  link_.auth.resume(tx, rx);   // past every counter of the old key too
  link_.set_fleet(m.fleet_id);   // the ACK goes out at the new address (and signed with the new key)
  link_.key_change = m.erase ? kKeyErase & 3u : kKeyStore & 3u;
  link_.persisted_once = false;  // the counters are stored again with the key
  ack(id, seq);
  send_event(EventKind::KeyStored, m.erase ? 0 : 1);
}

}  // namespace core
}  // namespace rovernav
