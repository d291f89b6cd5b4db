// The rover's own detour round an obstacle its sonar has just found, without the host, and its
// memory of what is near its body.
//
// The echoes become disks to keep the rover's centre out of (the echo's point, widened by half
// the beam at its range, which covers the arc the cone cuts at that range, and by the
// clearance). The memory: a sweep's start keeps the echoes beside the front of the body, behind
// the sensor, where no ping of the new sweep reaches (keep_near), and forgets the rest; the kept
// ones count for its turns, its backing out and its detour, not for the leg's check after the
// sweep. When every disk is held, the one farthest from the rover gives way. If the next leg passes
// through one, a breadth-first wavefront on a small grid (kCells x kCells cells of kCellMm,
// centred between the rover and a rejoin point further along its path) finds a way round, and
// its turning points become a detour of at most kMaxDetour waypoints.
//
// Memory: the wavefront's working arrays (a direction nibble per cell, the blocked cells and two
// frontier bitsets,
// kScratchBytes in all) live in a scratch buffer the caller lends (the Rover lends its idle
// path-staging buffer), so the planner adds only its echoes to the static RAM.
// Time: resumable. begin() sets a plan up; each step() does one bounded slice of it (kMarkCells
// cells tested against the disks, or one layer of the wavefront, or kWalkCells cells of the
// walk back) and says whether it is still running, found a detour or found none, so the rover
// keeps its 10 ms step (link, STATUS, STOP) while it plans. plan() runs it to the end at once
// (tests). ops() counts the work (native builds only); the Uno's time per slice is measured on
// the image in the AVR simulator, not estimated from it.
#pragma once
#include <stdint.h>

#include "body.h"

namespace rovernav {
namespace core {

struct Point {
  int16_t x_mm;
  int16_t y_mm;
};

enum class PlanStatus : uint8_t { Running, Found, NoWay };

class LocalPlanner {
 public:
  enum : uint8_t { kCells = 12, kMaxEchoes = 9, kMaxDetour = 4, kMarkCells = 18, kWalkCells = 2 };
  enum : int16_t { kCellMm = 80 };
  enum : uint16_t {
    kCellCount = kCells * kCells,
    kScratchBytes = kCellCount / 2 + 3 * ((kCellCount + 7) / 8),
  };

  void clear() { n_ = kept_ = 0; }
  uint8_t echoes() const { return n_; }
  /// Keeps the echoes beside the front of the body: within keep_mm of here, and from 0 to
  /// behind_mm ahead of it along the heading (fx_q8, fy_q8: its unit vector times 256), behind
  /// the sensor, where a sweep from there has no beam. The others are forgotten: ahead of the
  /// sensor the sweep looks afresh, and what lies behind the centre a turn's check does not need
  /// (backing out, the way the rover came, would only take it nearer). The kept ones are the
  /// body's memory; those added after them are fresh (the sweep's).
  void keep_near(Point here, uint16_t keep_mm, int16_t fx_q8, int16_t fy_q8, int16_t behind_mm);
  uint8_t kept() const { return kept_; }
  /// An obstacle point (fresh) to keep the rover's centre at least radius_mm away from. When all
  /// kMaxEchoes are held, the echo farthest from here (the rover) gives way to a nearer one.
  void add(Point p, uint16_t radius_mm, Point here);
  /// Whether the segment a-b passes within an obstacle disk (each disk shrunk by shrink_mm; with
  /// fresh_only, the fresh disks alone). A disk behind a (the segment's nearest point to its
  /// centre is a) does not block: from inside it, the segment leads away.
  bool blocks(Point a, Point b, uint16_t shrink_mm = 0, bool fresh_only = false) const;
  /// Whether point p is inside an obstacle disk.
  bool inside(Point p) const;
  /// Whether some echo's arc (its disk less the clearance it was widened by) comes within
  /// reach_mm of point p; with kept_reach_mm, whether a kept echo's point does within that.
  bool within(Point p, uint16_t clearance_mm, uint16_t reach_mm, uint16_t kept_reach_mm) const;
  /// Whether some echo, taken as a face that runs from it back along the heading (fx_q8, fy_q8:
  /// the heading's unit vector times 256) for kFaceRunMm, passes beside a body at p within
  /// kSideReachMm of its centre line (the echo's arc's half-width added) but not through it
  /// (kHalfWidthMm, the arc subtracted): a face seen abeam of the sonar, 100 mm ahead of the
  /// centre, that runs on alongside the rover. An echo kBehindMm or more behind p counts for
  /// nothing. The fresh echoes only (a kept one is no longer abeam of the sonar).
  bool beside(Point p, int16_t fx_q8, int16_t fy_q8, uint16_t clearance_mm) const;
  enum : int16_t { kFaceRunMm = 250, kSideReachMm = 140, kHalfWidthMm = kBodyHalfWidthMm, kBehindMm = 130 };
  /// Plans from start round the disks to goal. Writes the detour's waypoints (turning points,
  /// the goal last) to out and returns how many (1..kMaxDetour), or 0 when there is no way on
  /// the grid. scratch: kScratchBytes bytes the planner may use.
  uint8_t plan(Point start, Point goal, uint8_t* scratch, Point* out);
  /// The same in slices: begin() returns false when start or goal is off the grid or the goal
  /// is blocked (no plan); then step(), with the same scratch, until it returns Found (n_out
  /// waypoints in out) or NoWay. The scratch buffer must stay untouched until then.
  bool begin(Point start, Point goal, uint8_t* scratch);
  PlanStatus step(uint8_t* scratch, Point* out, uint8_t& n_out);
  bool planning() const { return phase_ != Phase::Idle; }
  void cancel() { phase_ = Phase::Idle; }
  /// Elementary operations of the last plan (cell tests, neighbour visits, disk tests), modulo
  /// 65,536 (a count of the Uno's size: a slice's is the difference of two, as uint16_t).
#if !defined(__AVR__)
  uint16_t ops() const { return ops_; }
#endif

 private:
  struct Disk {
    Point c;
    uint16_t r_mm;
  };
  bool cell_free(int16_t ix, int16_t iy) const;
  Point cell_centre(int16_t ix, int16_t iy) const;
  bool line_free(int16_t ax, int16_t ay, int16_t bx, int16_t by) const;

  enum class Phase : uint8_t { Idle, Mark, Search, Walk };

  Disk disks_[kMaxEchoes] = {};   // the kept echoes first, then the fresh ones
  uint8_t n_ = 0;
  uint8_t kept_ = 0;
  Point origin_ = {0, 0};  // the grid's lower-left corner
#if defined(__AVR__)
  // Nothing on the Uno reads the count (the image's time per slice is measured in the AVR
  // simulator): it keeps neither the counter nor its increments in the planner's loops.
  void count_op() const {}
  void restart_ops() {}
#else
  void count_op() const { ++ops_; }
  void restart_ops() { ops_ = 0; }
  mutable uint16_t ops_ = 0;
#endif
  // The plan under way.
  Point goal_ = {0, 0};
  Point anchor_ = {0, 0}, prev_ = {0, 0};   // the walk back: last kept point, last cell
  uint16_t start_i_ = 0, goal_i_ = 0;
  uint16_t i_ = 0;                          // Mark: next cell; Walk: the cell reached
  uint8_t layer_ = 0;
  uint8_t n_walk_ = 0;
  Phase phase_ = Phase::Idle;
  bool flip_ = false;                       // which frontier bitset is the current one
  bool reached_ = false;
  bool walk_init_ = false;
};

}  // namespace core
}  // namespace rovernav
