#include "local_planner.h"

#include "float_ops.h"
#include "progmem.h"

namespace rovernav {
namespace core {

namespace {

// The 8 neighbours, as (dx, dy); the opposite of direction k is k ^ 4 in this order.
const int8_t kDx[8] ROVERNAV_PROGMEM = {1, 1, 0, -1, -1, -1, 0, 1};
const int8_t kDy[8] ROVERNAV_PROGMEM = {0, 1, 1, 1, 0, -1, -1, -1};

inline bool bit(const uint8_t* bits, uint16_t i) { return (bits[i >> 3] >> (i & 7)) & 1; }
inline void set_bit(uint8_t* bits, uint16_t i) { bits[i >> 3] = static_cast<uint8_t>(bits[i >> 3] | (1u << (i & 7))); }
inline uint8_t nibble(const uint8_t* n, uint16_t i) { return (i & 1) ? static_cast<uint8_t>(n[i >> 1] >> 4) : static_cast<uint8_t>(n[i >> 1] & 0x0F); }
inline void set_nibble(uint8_t* n, uint16_t i, uint8_t v) {
  n[i >> 1] = (i & 1) ? static_cast<uint8_t>((n[i >> 1] & 0x0F) | (v << 4)) : static_cast<uint8_t>((n[i >> 1] & 0xF0) | v);
}

int32_t sq(int32_t v) { return v * v; }

// The squared distance between two points (out of line: three loops use it).
ROVERNAV_NOINLINE int32_t dist2(Point a, Point b) { return sq(a.x_mm - b.x_mm) + sq(a.y_mm - b.y_mm); }

// How far a lies from b along the unit vector (fx_q8, fy_q8) / 256, in 16 bits: the echoes are
// within a few metres of the rover. Out of line: three uses.
ROVERNAV_NOINLINE int16_t along_q8(Point a, Point b, int16_t fx_q8, int16_t fy_q8) {
  const int16_t dx = static_cast<int16_t>(a.x_mm - b.x_mm), dy = static_cast<int16_t>(a.y_mm - b.y_mm);
  return static_cast<int16_t>((static_cast<int32_t>(dx) * fx_q8 + static_cast<int32_t>(dy) * fy_q8) >> 8);
}

// How far c lies outside the span between a and b (0 within it), in 16 bits without overflow:
// the difference of two int16 is at most 65,535.
// Out of line: written out twice in blocks(), among its float locals, it took more flash than
// the two calls.
ROVERNAV_NOINLINE uint16_t outside_span(int16_t c, int16_t a, int16_t b) {
  const int16_t lo = a < b ? a : b, hi = a < b ? b : a;
  if (c < lo) return static_cast<uint16_t>(static_cast<uint16_t>(lo) - static_cast<uint16_t>(c));
  if (c > hi) return static_cast<uint16_t>(static_cast<uint16_t>(c) - static_cast<uint16_t>(hi));
  return 0;
}

}  // namespace

void LocalPlanner::keep_near(Point here, uint16_t keep_mm, int16_t fx_q8, int16_t fy_q8, int16_t behind_mm) {
  uint8_t k = 0;
  for (uint8_t i = 0; i < n_; ++i) {
    const Disk& d = disks_[i];
    const int16_t along = along_q8(d.c, here, fx_q8, fy_q8);
    if (along >= 0 && along < behind_mm && dist2(d.c, here) < sq(keep_mm)) disks_[k++] = d;
  }
  n_ = kept_ = k;
}

void LocalPlanner::add(Point p, uint16_t radius_mm, Point here) {
  uint8_t i = n_;
  if (n_ >= kMaxEchoes) {
    // Full (a sweep in clutter has more pings than there are disks): what is nearest the rover
    // matters most to its turns and its next leg; the echo farthest from it gives way.
    int32_t far = dist2(p, here);
    for (uint8_t k = 0; k < n_; ++k) {
      const int32_t d = dist2(disks_[k].c, here);
      if (d > far) {
        far = d;
        i = k;
      }
    }
    if (i >= kMaxEchoes) return;
    if (i < kept_) {
      // A kept echo gives way: the last kept one takes its place, and the new echo the slot
      // that frees, where the fresh ones begin.
      disks_[i] = disks_[kept_ - 1];
      i = --kept_;
    }
  } else {
    ++n_;
  }
  disks_[i].c = p;
  disks_[i].r_mm = radius_mm;
}

// A disk whose arc comes within reach is one whose radius, less the clearance plus the reach,
// covers p; inside() is within() with neither: one loop for both.
bool LocalPlanner::inside(Point p) const { return within(p, 0, 0, 0); }

bool LocalPlanner::within(Point p, uint16_t clearance_mm, uint16_t reach_mm, uint16_t kept_reach_mm) const {
  for (uint8_t i = 0; i < n_; ++i) {
    count_op();
    const Disk& d = disks_[i];
    const int32_t arc = d.r_mm > clearance_mm ? d.r_mm - clearance_mm : 0;   // half the arc's width
    const int32_t r = i < kept_ && kept_reach_mm ? kept_reach_mm : arc + reach_mm;
    if (dist2(p, d.c) < sq(r)) return true;
  }
  return false;
}

bool LocalPlanner::beside(Point p, int16_t fx_q8, int16_t fy_q8, uint16_t clearance_mm) const {
  for (uint8_t i = kept_; i < n_; ++i) {
    const Disk& d = disks_[i];
    const int16_t arc = static_cast<int16_t>(d.r_mm > clearance_mm ? d.r_mm - clearance_mm : 0);
    const int16_t along = along_q8(d.c, p, fx_q8, fy_q8);
    int16_t side = along_q8(d.c, p, fy_q8, static_cast<int16_t>(-fx_q8));   // to the right
    if (side < 0) side = static_cast<int16_t>(-side);
    if (along > -kBehindMm && along < kFaceRunMm && side < kSideReachMm + arc && side + arc > kHalfWidthMm) return true;
  }
  return false;
}

bool LocalPlanner::blocks(Point a, Point b, uint16_t shrink_mm, bool fresh_only) const {
  // A disk whose centre lies farther than its radius outside the segment's bounding box cannot
  // reach the segment: an integer test that spares most disks the float geometry (the walk back
  // tests three cells a slice against every disk).
  const float vx = to_float(b.x_mm - a.x_mm), vy = to_float(b.y_mm - a.y_mm);
  for (uint8_t i = fresh_only ? kept_ : 0; i < n_; ++i) {
    count_op();
    const Disk& d = disks_[i];
    if (d.r_mm <= shrink_mm) continue;
    const uint16_t r = static_cast<uint16_t>(d.r_mm - shrink_mm);
    if (outside_span(d.c.x_mm, a.x_mm, b.x_mm) > r || outside_span(d.c.y_mm, a.y_mm, b.y_mm) > r) continue;
    float t;
    const float d2 = segment_distance2(to_float(d.c.x_mm - a.x_mm), to_float(d.c.y_mm - a.y_mm), vx, vy, t);
    const float rf = static_cast<float>(r);
    if (d2 < rf * rf && positive(t)) return true;
  }
  return false;
}

ROVERNAV_NOINLINE Point LocalPlanner::cell_centre(int16_t ix, int16_t iy) const {
  Point p;
  p.x_mm = static_cast<int16_t>(origin_.x_mm + ix * kCellMm + kCellMm / 2);
  p.y_mm = static_cast<int16_t>(origin_.y_mm + iy * kCellMm + kCellMm / 2);
  return p;
}

bool LocalPlanner::cell_free(int16_t ix, int16_t iy) const { return !inside(cell_centre(ix, iy)); }

// The scratch buffer: direction nibbles (0 = not reached; k + 1 = step k leads towards the
// goal; 9 = the goal), the blocked cells, and two frontier bitsets.
namespace {
constexpr uint16_t kBits = (LocalPlanner::kCellCount + 7) / 8;

// The cell, along one axis, of a point d_mm from the grid's origin, as d_mm / kCellMm truncates
// (0 for -kCellMm < d_mm < 0); kNoCell off the grid. The range on the unsigned sum, the cell by an
// unsigned division: the signed one was the image's only use of the library's signed 16-bit
// division (38 bytes).
enum : uint8_t { kNoCell = 0xFF };
ROVERNAV_NOINLINE uint8_t grid_cell(int d_mm) {
  const unsigned below = LocalPlanner::kCellMm - 1;   // the offsets truncated to cell 0 from below
  if (static_cast<unsigned>(d_mm) + below >= LocalPlanner::kCells * LocalPlanner::kCellMm + below) return kNoCell;
  return d_mm < 0 ? 0 : static_cast<uint8_t>(static_cast<unsigned>(d_mm) / LocalPlanner::kCellMm);
}
}

bool LocalPlanner::begin(Point start, Point goal, uint8_t* scratch) {
  restart_ops();
  phase_ = Phase::Idle;
  const int16_t half = static_cast<int16_t>(kCells * kCellMm / 2);
  origin_.x_mm = static_cast<int16_t>((start.x_mm + goal.x_mm) / 2 - half);
  origin_.y_mm = static_cast<int16_t>((start.y_mm + goal.y_mm) / 2 - half);
  const uint8_t sx = grid_cell(start.x_mm - origin_.x_mm), sy = grid_cell(start.y_mm - origin_.y_mm);
  const uint8_t gx = grid_cell(goal.x_mm - origin_.x_mm), gy = grid_cell(goal.y_mm - origin_.y_mm);
  if (sx >= kCells || sy >= kCells || gx >= kCells || gy >= kCells) return false;
  if (inside(goal)) return false;
  anchor_ = prev_ = start;   // where the walk back starts
  goal_ = goal;
  start_i_ = static_cast<uint16_t>(sy * kCells + sx);
  goal_i_ = static_cast<uint16_t>(gy * kCells + gx);
  for (uint16_t i = 0; i < kScratchBytes; ++i) scratch[i] = 0;
  i_ = 0;
  phase_ = Phase::Mark;
  return true;
}

PlanStatus LocalPlanner::step(uint8_t* scratch, Point* out, uint8_t& n_out) {
  uint8_t* dir = scratch;
  uint8_t* blocked = scratch + kCellCount / 2;
  uint8_t* cur = blocked + kBits + (flip_ ? kBits : 0);
  uint8_t* nxt = blocked + kBits + (flip_ ? 0 : kBits);
  switch (phase_) {
    case Phase::Idle:
      return PlanStatus::NoWay;
    case Phase::Mark: {
      // kMarkCells cells a slice: each is tested against every disk.
      const uint16_t end = i_ + kMarkCells < kCellCount ? static_cast<uint16_t>(i_ + kMarkCells) : static_cast<uint16_t>(kCellCount);
      for (; i_ < end; ++i_) {
        const int16_t ix = static_cast<int16_t>(i_ % kCells), iy = static_cast<int16_t>(i_ / kCells);
        if (!cell_free(ix, iy)) set_bit(blocked, i_);
      }
      if (i_ < kCellCount) return PlanStatus::Running;
      set_nibble(dir, goal_i_, 9);
      set_bit(cur, goal_i_);
      reached_ = start_i_ == goal_i_;
      layer_ = 0;
      phase_ = reached_ ? Phase::Walk : Phase::Search;
      walk_init_ = true;
      return PlanStatus::Running;
    }
    case Phase::Search: {
      // One layer of the breadth-first wavefront from the goal a slice; no corner cutting.
      bool any = false;
      for (uint16_t i = 0; i < kBits; ++i) nxt[i] = 0;
      for (uint16_t c = 0; c < kCellCount; ++c) {
        count_op();
        if (!bit(cur, c)) continue;
        const int16_t cx = static_cast<int16_t>(c % kCells), cy = static_cast<int16_t>(c / kCells);
        for (uint8_t k = 0; k < 8; ++k) {
          count_op();
          const int16_t nx = static_cast<int16_t>(cx + flash_read_i8(&kDx[k])), ny = static_cast<int16_t>(cy + flash_read_i8(&kDy[k]));
          if (nx < 0 || ny < 0 || nx >= kCells || ny >= kCells) continue;
          const uint16_t n = static_cast<uint16_t>(ny * kCells + nx);
          if (nibble(dir, n) != 0) continue;
          if (bit(blocked, n) && n != start_i_) continue;
          if ((k & 1) && (bit(blocked, static_cast<uint16_t>(cy * kCells + nx)) ||
                          bit(blocked, static_cast<uint16_t>(ny * kCells + cx)))) continue;
          set_nibble(dir, n, static_cast<uint8_t>(((k ^ 4) & 7) + 1));  // from n, step back towards c
          set_bit(nxt, n);
          any = true;
          if (n == start_i_) reached_ = true;
        }
      }
      flip_ = !flip_;
      ++layer_;
      if (reached_) {
        phase_ = Phase::Walk;
        return PlanStatus::Running;
      }
      if (!any || layer_ >= kCellCount) {
        phase_ = Phase::Idle;
        return PlanStatus::NoWay;
      }
      return PlanStatus::Running;
    }
    case Phase::Walk:
      break;
  }
  // Walk from the start towards the goal, kWalkCells cells a slice; keep a turning point
  // wherever the straight line from the last kept point would cross a disk.
  if (walk_init_) {
    walk_init_ = false;
    n_walk_ = 0;
    i_ = start_i_;
  }
  for (uint8_t k = 0; k < kWalkCells; ++k) {
    const int16_t x = static_cast<int16_t>(i_ % kCells), y = static_cast<int16_t>(i_ / kCells);
    const uint8_t d = nibble(dir, i_);
    const bool at_goal = d == 9 || i_ == goal_i_;
    const Point here = at_goal ? goal_ : cell_centre(x, y);
    if (blocks(anchor_, here)) {
      if (n_walk_ >= kMaxDetour - 1 || d == 0) {
        phase_ = Phase::Idle;
        return PlanStatus::NoWay;
      }
      out[n_walk_++] = prev_;
      anchor_ = prev_;
    }
    if (at_goal) {
      out[n_walk_++] = goal_;
      n_out = n_walk_;
      phase_ = Phase::Idle;
      return PlanStatus::Found;
    }
    if (d == 0) {   // off the wavefront: cannot happen on a reached grid
      phase_ = Phase::Idle;
      return PlanStatus::NoWay;
    }
    prev_ = here;
    i_ = static_cast<uint16_t>((y + flash_read_i8(&kDy[d - 1])) * kCells + (x + flash_read_i8(&kDx[d - 1])));
  }
  return PlanStatus::Running;
}

uint8_t LocalPlanner::plan(Point start, Point goal, uint8_t* scratch, Point* out) {
  if (!begin(start, goal, scratch)) return 0;
  uint8_t n = 0;
  for (;;) {
    const PlanStatus st = step(scratch, out, n);
    if (st == PlanStatus::Found) return n;
    if (st == PlanStatus::NoWay) return 0;
  }
}

}  // namespace core
}  // namespace rovernav

