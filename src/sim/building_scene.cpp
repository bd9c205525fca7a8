#include "gmm_mcl/sim/building_scene.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <map>
#include <stdexcept>
#include <utility>

#include "gmm_mcl/sim/uniform_rng.h"

namespace gmm_mcl {
namespace sim {
namespace {

constexpr double kEps = 1e-9;
constexpr int kMaxAttempts = 32;
// Doors keep this far (plus half a wall) from the ends of their wall.
constexpr double kDoorEndMarginM = 0.4;
// Kept free of furniture: in front of a door (each side), over an opening between the parts of
// a merged room, and where corridors meet.
constexpr double kDoorKeepClearDepthM = 1.6;
constexpr double kDoorKeepClearSideM = 0.45;
constexpr double kOpeningKeepClearDepthM = 1.2;
constexpr double kJunctionKeepClearDepthM = 2.6;
// Furniture nearer than this to a wall stands against it.
constexpr double kSnapToWallM = 0.05;
// Furniture covers at most this fraction of a space's floor.
constexpr double kMaxFurnitureCover = 0.3;

using Rng = UniformRng;

PlanRect rect(double x0, double y0, double x1, double y1) {
  PlanRect r;
  r.lo_m = Eigen::Vector2d(x0, y0);
  r.hi_m = Eigen::Vector2d(x1, y1);
  return r;
}

bool overlaps(const PlanRect& a, const PlanRect& b) {
  return (a.lo_m.array() < b.hi_m.array() - kEps).all() &&
         (b.lo_m.array() < a.hi_m.array() - kEps).all();
}

bool insideRect(const PlanRect& inner, const PlanRect& outer) {
  return (inner.lo_m.array() >= outer.lo_m.array() - 1e-7).all() &&
         (inner.hi_m.array() <= outer.hi_m.array() + 1e-7).all();
}

PlanRect grown(const PlanRect& r, double d) {
  PlanRect g = r;
  g.lo_m.array() -= d;
  g.hi_m.array() += d;
  return g;
}

// Cuts r across `axis` at coordinate `at`: the part below and, from at + width on, the part
// above (a strip of `width` between them for corridors).
void cut(const PlanRect& r, int axis, double at, double width, PlanRect* below, PlanRect* strip,
         PlanRect* above) {
  *below = *strip = *above = r;
  below->hi_m[axis] = at;
  strip->lo_m[axis] = at;
  strip->hi_m[axis] = at + width;
  above->lo_m[axis] = at + width;
}

// ---- floor plan ----

struct Cell {
  PlanRect r;
  int space = -1;
  bool corridor = false;
};

// Where two cells meet: the segment [lo, hi] of the line x = plane (normal_axis 0) or y = plane.
struct Boundary {
  enum Kind { kWall, kOpen, kPartial };
  int cell_a = -1, cell_b = -1;
  int normal_axis = 0;
  double plane = 0.0, lo = 0.0, hi = 0.0;
  Kind kind = kWall;
  double open_lo = 0.0, open_hi = 0.0;  // a partial wall's opening
  double length() const { return hi - lo; }
  // True when there is wall at coordinate s along the line (doors are never at the ends).
  bool solidAt(double s) const {
    if (kind == kOpen || s < lo - 1e-7 || s > hi + 1e-7) return false;
    return kind == kWall || s <= open_lo + 1e-7 || s >= open_hi - 1e-7;
  }
};

std::vector<Boundary> findBoundaries(const std::vector<Cell>& cells) {
  std::vector<Boundary> out;
  for (size_t i = 0; i < cells.size(); ++i) {
    for (size_t j = i + 1; j < cells.size(); ++j) {
      const PlanRect &a = cells[i].r, &b = cells[j].r;
      for (int k = 0; k < 2; ++k) {
        double plane;
        if (std::abs(a.hi_m[k] - b.lo_m[k]) < 1e-7) {
          plane = a.hi_m[k];
        } else if (std::abs(b.hi_m[k] - a.lo_m[k]) < 1e-7) {
          plane = a.lo_m[k];
        } else {
          continue;
        }
        const int o = 1 - k;
        const double lo = std::max(a.lo_m[o], b.lo_m[o]), hi = std::min(a.hi_m[o], b.hi_m[o]);
        if (hi - lo < 1e-6) continue;
        Boundary bd;
        bd.cell_a = static_cast<int>(i);
        bd.cell_b = static_cast<int>(j);
        bd.normal_axis = k;
        bd.plane = plane;
        bd.lo = lo;
        bd.hi = hi;
        out.push_back(bd);
      }
    }
  }
  return out;
}

struct Plan {
  std::vector<Cell> cells;
  std::vector<BuildingSpace> spaces;
  std::vector<Boundary> boundaries;
  std::vector<BuildingDoor> doors;
};

// Corridors: one along the longer side, one across each half (on different sides), and with
// some luck a third along the longer side inside the largest block. Returns the blocks.
std::vector<PlanRect> layCorridors(const BuildingParams& p, Rng* rng, std::vector<Cell>* cells) {
  const PlanRect all = rect(0.0, 0.0, p.width_m, p.length_m);
  const int la = p.width_m >= p.length_m ? 0 : 1;  // the main corridor runs along la
  const int ca = 1 - la;
  auto width = [&] { return rng->uniform(p.corridor_min_width_m, p.corridor_max_width_m); };
  auto addCorridor = [&](const PlanRect& r) {
    Cell c;
    c.r = r;
    c.corridor = true;
    cells->push_back(c);
  };
  const double w0 = width();
  const double len_c = all.hi_m[ca] - all.lo_m[ca];
  const double at0 = rng->uniform(0.38, 0.62) * len_c - 0.5 * w0;
  PlanRect half_lo, strip, half_hi;
  cut(all, ca, at0, w0, &half_lo, &strip, &half_hi);
  addCorridor(strip);
  // Across each half, on different sides of the middle.
  const double len_l = all.hi_m[la] - all.lo_m[la];
  const bool swap = rng->chance(0.5);
  std::vector<PlanRect> blocks;
  for (int h = 0; h < 2; ++h) {
    const PlanRect& half = h == 0 ? half_lo : half_hi;
    const bool low_side = (h == 0) != swap;
    const double f = low_side ? rng->uniform(0.18, 0.42) : rng->uniform(0.58, 0.82);
    const double w = width();
    PlanRect a, s, b;
    cut(half, la, f * len_l - 0.5 * w, w, &a, &s, &b);
    addCorridor(s);
    blocks.push_back(a);
    blocks.push_back(b);
  }
  // A third corridor along la through the largest block, from the shell to a cross corridor.
  size_t largest = 0;
  for (size_t i = 1; i < blocks.size(); ++i) {
    if (blocks[i].area_m2() > blocks[largest].area_m2()) largest = i;
  }
  const PlanRect big = blocks[largest];
  const double extent = big.hi_m[ca] - big.lo_m[ca];
  const double w3 = width();
  if (extent >= 4.0 * p.min_room_side_m + w3 && rng->chance(0.75)) {
    const double at = big.lo_m[ca] + rng->uniform(0.35, 0.65) * extent - 0.5 * w3;
    PlanRect a, s, b;
    cut(big, ca, at, w3, &a, &s, &b);
    addCorridor(s);
    blocks[largest] = a;
    blocks.push_back(b);
  }
  return blocks;
}

// Splits the blocks into `count` room cells: each time a cell drawn with probability growing with
// its area (area^1.5), cut across its longer side when elongated, between 25 % and 75 % and
// never leaving a side under min_room_side_m. False when no cell can be cut any more.
bool splitRooms(const BuildingParams& p, const std::vector<PlanRect>& blocks, int count, Rng* rng,
                std::vector<PlanRect>* rooms) {
  *rooms = blocks;
  const double m = p.min_room_side_m;
  while (static_cast<int>(rooms->size()) < count) {
    std::vector<double> weight(rooms->size(), 0.0);
    double total = 0.0;
    for (size_t i = 0; i < rooms->size(); ++i) {
      const Eigen::Vector2d s = (*rooms)[i].hi_m - (*rooms)[i].lo_m;
      if (s.maxCoeff() >= 2.0 * m) weight[i] = std::pow((*rooms)[i].area_m2(), 1.5);
      total += weight[i];
    }
    if (!(total > 0.0)) return false;
    double pick = rng->uniform() * total;
    size_t i = 0;
    while (i + 1 < rooms->size() && (pick -= weight[i]) >= 0.0) ++i;
    while (weight[i] == 0.0) --i;  // rounding at the end of the list
    const PlanRect r = (*rooms)[i];
    const Eigen::Vector2d s = r.hi_m - r.lo_m;
    int axis;
    if (s.x() >= 2.0 * m && s.y() >= 2.0 * m) {
      const double aspect = std::max(s.x(), s.y()) / std::min(s.x(), s.y());
      axis = aspect > 1.4 ? (s.x() > s.y() ? 0 : 1) : rng->below(2);
    } else {
      axis = s.x() >= 2.0 * m ? 0 : 1;
    }
    const double lo = std::max(m, 0.25 * s[axis]), hi = std::min(s[axis] - m, 0.75 * s[axis]);
    const double at = r.lo_m[axis] + (hi > lo ? rng->uniform(lo, hi) : 0.5 * s[axis]);
    PlanRect a, strip, b;
    cut(r, axis, at, 0.0, &a, &strip, &b);
    (*rooms)[i] = a;
    rooms->push_back(b);
  }
  return true;
}

// A door of `width` somewhere on boundary b, away from its ends.
BuildingDoor makeDoor(const Plan& plan, const Boundary& b, const BuildingParams& p, Rng* rng) {
  BuildingDoor d;
  d.space_a = plan.cells[b.cell_a].space;
  d.space_b = plan.cells[b.cell_b].space;
  d.normal_axis = b.normal_axis;
  d.plane_m = b.plane;
  d.width_m = rng->uniform(p.door_min_width_m, p.door_max_width_m);
  d.height_m = p.door_height_m;
  const double margin = 0.5 * p.wall_thickness_m + kDoorEndMarginM + 0.5 * d.width_m;
  d.centre_m = rng->uniform(b.lo + margin, b.hi - margin);
  return d;
}

bool doorFits(const Boundary& b, const BuildingParams& p) {
  return b.kind == Boundary::kWall &&
         b.length() >= p.door_max_width_m + 2.0 * (0.5 * p.wall_thickness_m + kDoorEndMarginM);
}

// The whole floor plan for one draw of the generator; false when this draw cannot give the
// requested rooms and doors.
bool makePlan(const BuildingParams& p, Rng* rng, Plan* plan) {
  plan->cells.clear();
  const std::vector<PlanRect> blocks = layCorridors(p, rng, &plan->cells);
  std::vector<PlanRect> rooms;
  if (!splitRooms(p, blocks, p.room_count + p.merged_rooms, rng, &rooms)) return false;
  for (const PlanRect& r : rooms) {
    Cell c;
    c.r = r;
    plan->cells.push_back(c);
  }
  // Spaces: the corridor network, then one per room cell until merged.
  std::vector<int> space_of(plan->cells.size());
  int next = 1;
  for (size_t i = 0; i < plan->cells.size(); ++i) {
    space_of[i] = plan->cells[i].corridor ? 0 : next++;
  }
  plan->boundaries = findBoundaries(plan->cells);
  for (Boundary& b : plan->boundaries) {
    if (plan->cells[b.cell_a].corridor && plan->cells[b.cell_b].corridor) b.kind = Boundary::kOpen;
  }
  // Merges: two single-cell rooms that share at least 2.5 m become one room.
  std::vector<int> cells_in(next, 1);
  int merged = 0;
  for (int tries = 0; merged < p.merged_rooms && tries < 200; ++tries) {
    Boundary& b = plan->boundaries[rng->below(static_cast<int>(plan->boundaries.size()))];
    const int sa = space_of[b.cell_a], sb = space_of[b.cell_b];
    if (sa == 0 || sb == 0 || sa == sb || cells_in[sa] != 1 || cells_in[sb] != 1 ||
        b.length() < 2.5) {
      continue;
    }
    const int o = 1 - b.normal_axis;
    const PlanRect &ra = plan->cells[b.cell_a].r, &rb = plan->cells[b.cell_b].r;
    const bool same_side =
        std::abs(ra.lo_m[o] - rb.lo_m[o]) < 1e-7 && std::abs(ra.hi_m[o] - rb.hi_m[o]) < 1e-7;
    // Side by side with equal sides: one rectangle, split by a partial wall; else an L or a T,
    // mostly open.
    if (same_side || rng->chance(0.3)) {
      const double f = rng->uniform(0.35, 0.6) * b.length();
      b.kind = Boundary::kPartial;
      if (rng->chance(0.5)) {
        b.open_lo = b.lo + f;
        b.open_hi = b.hi;
      } else {
        b.open_lo = b.lo;
        b.open_hi = b.hi - f;
      }
    } else {
      b.kind = Boundary::kOpen;
    }
    for (int& s : space_of) {
      if (s == sb) s = sa;
    }
    cells_in[sa] = 2;
    cells_in[sb] = 0;
    ++merged;
  }
  if (merged < p.merged_rooms) return false;
  // Compact space numbers: 0 the corridors, then rooms in cell order.
  std::map<int, int> renumber{{0, 0}};
  for (int s : space_of) {
    if (!renumber.count(s)) {
      const int n = static_cast<int>(renumber.size());
      renumber[s] = n;
    }
  }
  plan->spaces.assign(renumber.size(), BuildingSpace());
  plan->spaces[0].kind = "corridor";
  plan->spaces[0].corridor = true;
  for (size_t i = 0; i < plan->cells.size(); ++i) {
    plan->cells[i].space = renumber[space_of[i]];
    plan->spaces[plan->cells[i].space].cells.push_back(plan->cells[i].r);
  }
  if (static_cast<int>(plan->spaces.size()) != p.room_count + 1) return false;
  // Also walls between two cells of one merged room that met on a second boundary.
  for (Boundary& b : plan->boundaries) {
    if (b.kind == Boundary::kWall && plan->cells[b.cell_a].space == plan->cells[b.cell_b].space) {
      b.kind = Boundary::kOpen;
    }
  }

  // Doors: every room joined to what is already reached (the corridors first), one door per pair
  // of spaces, then the extra doors between pairs without one.
  const int n_spaces = static_cast<int>(plan->spaces.size());
  std::vector<char> reached(n_spaces, 0), has_door(n_spaces * n_spaces, 0);
  reached[0] = 1;
  plan->doors.clear();
  auto pairOf = [&](const Boundary& b) {
    return std::make_pair(plan->cells[b.cell_a].space, plan->cells[b.cell_b].space);
  };
  auto addDoor = [&](const Boundary& b) {
    const auto sp = pairOf(b);
    plan->doors.push_back(makeDoor(*plan, b, p, rng));
    has_door[sp.first * n_spaces + sp.second] = has_door[sp.second * n_spaces + sp.first] = 1;
    reached[sp.first] = reached[sp.second] = 1;
  };
  std::vector<size_t> order(plan->boundaries.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = i;
  for (size_t i = order.size(); i > 1; --i) std::swap(order[i - 1], order[rng->below(int(i))]);
  for (size_t i : order) {
    const Boundary& b = plan->boundaries[i];
    const auto sp = pairOf(b);
    if (!doorFits(b, p) || sp.first == sp.second) continue;
    const int room = sp.first == 0 ? sp.second : sp.second == 0 ? sp.first : -1;
    if (room > 0 && !reached[room] && rng->chance(0.85)) addDoor(b);
  }
  while (std::find(reached.begin(), reached.end(), 0) != reached.end()) {
    std::vector<size_t> options;
    for (size_t i : order) {
      const Boundary& b = plan->boundaries[i];
      const auto sp = pairOf(b);
      if (doorFits(b, p) && reached[sp.first] != reached[sp.second]) options.push_back(i);
    }
    if (options.empty()) return false;
    addDoor(plan->boundaries[options[rng->below(static_cast<int>(options.size()))]]);
  }
  for (int extra = 0; extra < p.extra_doors; ++extra) {
    std::vector<size_t> options;
    for (size_t i : order) {
      const Boundary& b = plan->boundaries[i];
      const auto sp = pairOf(b);
      if (doorFits(b, p) && sp.first != sp.second && !has_door[sp.first * n_spaces + sp.second]) {
        options.push_back(i);
      }
    }
    if (options.empty()) return false;
    addDoor(plan->boundaries[options[rng->below(static_cast<int>(options.size()))]]);
  }
  return true;
}

// ---- walls ----

// Wall boxes along the boundaries, with gaps for doors and the openings of partial walls and a
// lintel over each door. A wall end where another wall crosses or meets it at right angles
// runs on by half a thickness, so that corners are closed.
void buildWalls(const Plan& plan, const BuildingParams& p, PrimitiveScene* scene) {
  const double t = p.wall_thickness_m, h = p.height_m;
  const Eigen::Vector2d size(p.width_m, p.length_m);
  auto meets = [&](const Boundary& self, double end) {
    const int k = self.normal_axis;
    if (end <= 1e-7 || end >= size[1 - k] - 1e-7) return false;  // at the shell
    for (const Boundary& o : plan.boundaries) {
      if (o.normal_axis == k || std::abs(o.plane - end) > 1e-7) continue;
      if (o.solidAt(self.plane)) return true;
    }
    return false;
  };
  auto wallBox = [&](const Boundary& b, double s0, double s1, double z0) {
    const int k = b.normal_axis;
    Eigen::Vector3d lo, hi;
    lo[k] = std::max(0.0, b.plane - 0.5 * t);
    hi[k] = std::min(size[k], b.plane + 0.5 * t);
    lo[1 - k] = std::max(0.0, s0);
    hi[1 - k] = std::min(size[1 - k], s1);
    lo[2] = z0;
    hi[2] = h;
    Box bx;
    bx.min_m = lo;
    bx.max_m = hi;
    scene->boxes.push_back(bx);
  };
  for (const Boundary& b : plan.boundaries) {
    if (b.kind == Boundary::kOpen) continue;
    std::vector<std::pair<double, double>> gaps;
    if (b.kind == Boundary::kPartial) gaps.emplace_back(b.open_lo, b.open_hi);
    for (const BuildingDoor& d : plan.doors) {
      if (d.normal_axis != b.normal_axis || std::abs(d.plane_m - b.plane) > 1e-7) continue;
      if (d.centre_m < b.lo || d.centre_m > b.hi) continue;
      gaps.emplace_back(d.centre_m - 0.5 * d.width_m, d.centre_m + 0.5 * d.width_m);
      wallBox(b, gaps.back().first, gaps.back().second, d.height_m);  // lintel
    }
    std::sort(gaps.begin(), gaps.end());
    double s = b.lo - (meets(b, b.lo) ? 0.5 * t : 0.0);
    for (const auto& g : gaps) {
      if (g.first > s + 1e-7) wallBox(b, s, g.first, 0.0);
      s = std::max(s, g.second);
    }
    const double end = b.hi + (meets(b, b.hi) ? 0.5 * t : 0.0);
    if (end > s + 1e-7) wallBox(b, s, end, 0.0);
  }
}

// ---- furniture ----

// A piece of furniture in its own frame: footprint [0, length] x [0, depth], the back at y = 0
// (against the wall for wall items), z up from the floor.
struct Item {
  double length = 0.0, depth = 0.0;
  std::vector<Box> boxes;
  std::vector<Cylinder> cylinders;
  double gap = 0.9;  // free space kept between it and other furniture
};

// Turns by quarter turns q about z, then moves by origin.
Eigen::Vector2d place2(const Eigen::Vector2d& v, int q, const Eigen::Vector2d& origin) {
  switch (q & 3) {
    case 0:
      return origin + v;
    case 1:
      return origin + Eigen::Vector2d(-v.y(), v.x());
    case 2:
      return origin - v;
    default:
      return origin + Eigen::Vector2d(v.y(), -v.x());
  }
}

PlanRect placedRect(const Eigen::Vector2d& lo, const Eigen::Vector2d& hi, int q,
                    const Eigen::Vector2d& origin) {
  const Eigen::Vector2d a = place2(lo, q, origin), b = place2(hi, q, origin);
  PlanRect r;
  r.lo_m = a.cwiseMin(b);
  r.hi_m = a.cwiseMax(b);
  return r;
}

// Item builders. H: ceiling height.
Item shelf(Rng* r, double max_len, double H) {
  Item it;
  it.length = r->uniform(0.8, std::min(2.4, max_len));
  it.depth = r->uniform(0.3, 0.5);
  const double h = r->uniform(1.5, std::min(2.4, H - 0.3));
  const int n = r->between(3, 6);
  const double L = it.length, D = it.depth;
  it.boxes.push_back(makeBox(0, 0, 0, L, 0.02, h));
  it.boxes.push_back(makeBox(0, 0.02, 0, 0.03, D, h));
  it.boxes.push_back(makeBox(L - 0.03, 0.02, 0, L, D, h));
  const double step = (h - 0.03) / (n - 1);
  for (int b = 0; b < n; ++b) {
    const double z = b * step;
    it.boxes.push_back(makeBox(0.03, 0.02, z, L - 0.03, D, z + 0.03));
    if (b + 1 == n || !r->chance(0.75)) continue;
    // Things on the board: boxes of different sizes, left to right.
    double x = 0.03 + r->uniform(0.0, 0.2);
    while (true) {
      const double w = r->uniform(0.12, 0.5), d = r->uniform(0.15, D - 0.04);
      const double ht = r->uniform(0.08, std::max(0.09, std::min(0.4, step - 0.1)));
      if (x + w > L - 0.04) break;
      it.boxes.push_back(makeBox(x, 0.02, z + 0.03, x + w, 0.02 + d, z + 0.03 + ht));
      x += w + r->uniform(0.02, 0.4);
    }
  }
  return it;
}

Item cabinet(Rng* r, double max_len) {
  Item it;
  it.length = r->uniform(0.6, std::min(1.6, max_len));
  it.depth = r->uniform(0.4, 0.6);
  const double h = r->uniform(0.7, 1.25);
  it.boxes.push_back(makeBox(0, 0, 0, it.length, it.depth, h));
  if (r->chance(0.5)) {  // something on top
    const double w = r->uniform(0.2, 0.5), x = r->uniform(0.05, it.length - w - 0.02);
    it.boxes.push_back(makeBox(x, 0.05, h, x + w, it.depth - 0.05, h + r->uniform(0.1, 0.4)));
  } else if (r->chance(0.5)) {
    it.cylinders.push_back(makeCylinder(r->uniform(0.2, it.length - 0.2), 0.5 * it.depth, 0.08, h,
                                        h + r->uniform(0.2, 0.35)));
  }
  return it;
}

Item counter(Rng* r, double max_len, double H) {
  Item it;
  it.length = r->uniform(1.8, std::max(1.9, std::min(5.0, max_len)));
  it.depth = 0.62;
  it.boxes.push_back(makeBox(0, 0, 0, it.length, 0.6, 0.88));
  it.boxes.push_back(makeBox(0, 0, 0.88, it.length, 0.62, 0.92));  // worktop
  if (r->chance(0.6)) {                                            // wall cabinets above
    const double x0 = r->uniform(0.0, 0.3 * it.length);
    it.boxes.push_back(makeBox(x0, 0, 1.45, it.length - r->uniform(0.0, 0.3 * it.length), 0.35,
                               std::min(H - 0.5, 2.15)));
  }
  if (r->chance(0.5)) {  // a machine on the worktop
    const double x = r->uniform(0.1, it.length - 0.6);
    it.boxes.push_back(
        makeBox(x, 0.05, 0.92, x + r->uniform(0.3, 0.5), 0.45, 0.92 + r->uniform(0.2, 0.5)));
  }
  return it;
}

Item desk(Rng* r, double max_len) {
  Item it;
  const double L = r->uniform(1.1, std::min(1.8, max_len)), D = r->uniform(0.6, 0.8), h = 0.74;
  it.length = L;
  it.depth = D + 0.65;
  it.boxes.push_back(makeBox(0, 0, h - 0.03, L, D, h));
  it.boxes.push_back(makeBox(0, 0, 0, 0.03, D, h - 0.03));
  it.boxes.push_back(makeBox(L - 0.03, 0, 0, L, D, h - 0.03));
  it.boxes.push_back(makeBox(0.03, 0, 0.35, L - 0.03, 0.02, h - 0.03));
  if (r->chance(0.8)) {  // a monitor on a foot
    const double x = r->uniform(0.1, L - 0.65), w = r->uniform(0.45, 0.6);
    it.boxes.push_back(makeBox(x + 0.5 * w - 0.1, 0.08, h, x + 0.5 * w + 0.1, 0.2, h + 0.1));
    it.boxes.push_back(makeBox(x, 0.12, h + 0.1, x + w, 0.16, h + 0.1 + r->uniform(0.3, 0.4)));
  }
  if (r->chance(0.7)) {  // a chair
    const double x = r->uniform(0.25, L - 0.25);
    it.boxes.push_back(makeBox(x - 0.23, D + 0.1, 0, x + 0.23, D + 0.56, 0.46));
    it.boxes.push_back(makeBox(x - 0.23, D + 0.51, 0.46, x + 0.23, D + 0.56, 0.95));
  }
  return it;
}

Item sofa(Rng* r, double max_len) {
  Item it;
  const double L = r->uniform(1.5, std::min(2.8, max_len)), D = r->uniform(0.8, 0.95);
  it.length = L;
  it.depth = D;
  it.boxes.push_back(makeBox(0, 0, 0, L, D, 0.42));
  it.boxes.push_back(makeBox(0, 0, 0.42, L, 0.22, r->uniform(0.8, 0.95)));
  const double arm = r->uniform(0.6, 0.7);
  it.boxes.push_back(makeBox(0, 0.22, 0.42, 0.2, D, arm));
  it.boxes.push_back(makeBox(L - 0.2, 0.22, 0.42, L, D, arm));
  return it;
}

Item whiteboard(Rng* r, double max_len) {
  Item it;
  it.length = r->uniform(1.0, std::min(2.6, max_len));
  it.depth = 0.03;
  const double z0 = r->uniform(0.8, 1.0);
  it.boxes.push_back(makeBox(0, 0, z0, it.length, 0.03, z0 + r->uniform(0.7, 1.2)));
  it.gap = 0.4;
  return it;
}

Item bench(Rng* r, double max_len) {
  Item it;
  it.length = r->uniform(1.2, std::min(2.5, max_len));
  it.depth = 0.45;
  it.boxes.push_back(makeBox(0, 0, 0.4, it.length, 0.45, 0.45));
  it.boxes.push_back(makeBox(0.1, 0.05, 0, 0.2, 0.4, 0.4));
  it.boxes.push_back(makeBox(it.length - 0.2, 0.05, 0, it.length - 0.1, 0.4, 0.4));
  return it;
}

Item lockers(Rng* r, double max_len) {
  Item it;
  const int n = std::max(1, std::min(static_cast<int>(max_len / 0.45), r->between(2, 6)));
  it.length = n * 0.45;
  it.depth = 0.45;
  const double h = r->uniform(1.7, 1.95);
  for (int i = 0; i < n; ++i) {  // one box each, with a slight step between them
    it.boxes.push_back(makeBox(i * 0.45, 0, 0, (i + 1) * 0.45 - 0.01, 0.45 - 0.01 * (i % 2), h));
  }
  return it;
}

Item pilaster(Rng* r, double H) {
  Item it;
  it.length = r->uniform(0.3, 0.6);
  it.depth = r->uniform(0.12, 0.3);
  it.boxes.push_back(makeBox(0, 0, 0, it.length, it.depth, H));
  it.gap = 0.5;
  return it;
}

Item wallPartition(Rng* r, double max_depth, double H) {
  Item it;
  it.length = 0.1;
  it.depth = r->uniform(1.4, std::max(1.5, max_depth));
  it.boxes.push_back(makeBox(0, 0, 0, 0.1, it.depth, r->chance(0.5) ? H : r->uniform(1.6, 2.2)));
  it.gap = 1.0;
  return it;
}

Item table(Rng* r, double max_len) {
  Item it;
  const double L = r->uniform(1.2, std::max(1.3, std::min(3.4, max_len - 0.4)));
  const double W = r->uniform(0.7, 1.1), h = r->uniform(0.72, 0.76);
  it.length = L + 0.4;
  it.depth = W + 1.2;
  const double x0 = 0.2, y0 = 0.6;
  it.boxes.push_back(makeBox(x0, y0, h - 0.04, x0 + L, y0 + W, h));
  for (int i = 0; i < 4; ++i) {
    const double x = i % 2 ? x0 + L - 0.1 : x0 + 0.05, y = i / 2 ? y0 + W - 0.1 : y0 + 0.05;
    it.boxes.push_back(makeBox(x, y, 0, x + 0.05, y + 0.05, h - 0.04));
  }
  const int per_side = std::max(1, static_cast<int>(L / 0.7));
  for (int side = 0; side < 2; ++side) {
    for (int c = 0; c < per_side; ++c) {
      if (r->chance(0.25)) continue;
      const double x = x0 + (c + 0.5) * L / per_side + r->uniform(-0.08, 0.08);
      if (side == 0) {
        it.boxes.push_back(makeBox(x - 0.22, 0.05, 0, x + 0.22, 0.5, 0.46));
        it.boxes.push_back(makeBox(x - 0.22, 0.05, 0.46, x + 0.22, 0.1, 0.92));
      } else {
        const double y = y0 + W;
        it.boxes.push_back(makeBox(x - 0.22, y + 0.05, 0, x + 0.22, y + 0.5, 0.46));
        it.boxes.push_back(makeBox(x - 0.22, y + 0.45, 0.46, x + 0.22, y + 0.5, 0.92));
      }
    }
  }
  return it;
}

Item roundTable(Rng* r) {
  Item it;
  const double rad = r->uniform(0.4, 0.65);
  const double s = 2.0 * (rad + 0.55);
  it.length = it.depth = s;
  const double c = 0.5 * s;
  it.cylinders.push_back(makeCylinder(c, c, rad, 0.71, 0.75));
  it.cylinders.push_back(makeCylinder(c, c, 0.05, 0.03, 0.71));
  it.cylinders.push_back(makeCylinder(c, c, 0.25, 0.0, 0.03));
  const int stools = r->between(0, 4);
  const double a0 = r->uniform(0.0, 2.0 * M_PI);
  for (int i = 0; i < stools; ++i) {
    const double a = a0 + 2.0 * M_PI * i / std::max(stools, 3);
    it.cylinders.push_back(makeCylinder(c + (rad + 0.32) * std::cos(a),
                                        c + (rad + 0.32) * std::sin(a), 0.17, 0.0,
                                        r->uniform(0.42, 0.5)));
  }
  return it;
}

Item column(Rng* r, double H) {
  Item it;
  if (r->chance(0.6)) {
    const double rad = r->uniform(0.15, 0.35);
    it.length = it.depth = 2.0 * rad;
    it.cylinders.push_back(makeCylinder(rad, rad, rad, 0.0, H));
  } else {
    const double s = r->uniform(0.3, 0.6);
    it.length = it.depth = s;
    it.boxes.push_back(makeBox(0, 0, 0, s, s, H));
  }
  it.gap = 1.0;
  return it;
}

Item drums(Rng* r) {
  Item it;
  const int n = r->between(1, 4);
  const double rad = r->uniform(0.27, 0.33), h = r->uniform(0.85, 0.95);
  const bool square = n == 4 && r->chance(0.5);
  const int cols = square ? 2 : n, rows = square ? 2 : 1;
  it.length = cols * 2.0 * rad + (cols - 1) * 0.04;
  it.depth = rows * 2.0 * rad + (rows - 1) * 0.04;
  for (int i = 0; i < n; ++i) {
    const int cx = i % cols, cy = i / cols;
    const double x = rad + cx * (2.0 * rad + 0.04), y = rad + cy * (2.0 * rad + 0.04);
    it.cylinders.push_back(makeCylinder(x, y, rad, 0.0, h + r->uniform(-0.03, 0.03)));
  }
  return it;
}

Item crates(Rng* r) {
  Item it;
  const double w = r->uniform(0.5, 1.2), d = r->uniform(0.5, 1.2);
  it.length = w;
  it.depth = d;
  double z = 0.0, x0 = 0.0, y0 = 0.0, x1 = w, y1 = d;
  const int n = r->between(1, 3);
  for (int i = 0; i < n; ++i) {
    const double h = r->uniform(0.3, 0.8);
    it.boxes.push_back(makeBox(x0, y0, z, x1, y1, z + h));
    z += h;
    const double nw = (x1 - x0) * r->uniform(0.5, 0.9), nd = (y1 - y0) * r->uniform(0.5, 0.9);
    x0 += r->uniform(0.0, x1 - x0 - nw);
    y0 += r->uniform(0.0, y1 - y0 - nd);
    x1 = x0 + nw;
    y1 = y0 + nd;
    if (z > 1.8) break;
  }
  return it;
}

Item plant(Rng* r) {
  Item it;
  const double leaves = r->uniform(0.3, 0.45);
  it.length = it.depth = 2.0 * leaves;
  it.cylinders.push_back(makeCylinder(leaves, leaves, r->uniform(0.16, 0.22), 0.0, 0.45));
  it.cylinders.push_back(makeCylinder(leaves, leaves, leaves, 0.45, 0.45 + r->uniform(0.5, 1.1)));
  it.gap = 0.6;
  return it;
}

Item machine(Rng* r, double H) {
  Item it;
  const double L = r->uniform(0.8, 1.8), D = r->uniform(0.7, 1.4), h = r->uniform(1.0, 1.8);
  it.length = L;
  it.depth = D;
  it.boxes.push_back(makeBox(0, 0, 0, L, D, h));
  if (r->chance(0.5)) {
    const double rad = r->uniform(0.15, std::min(0.35, 0.45 * std::min(L, D)));
    it.cylinders.push_back(
        makeCylinder(rad + 0.05, rad + 0.05, rad, h, std::min(H - 0.3, h + r->uniform(0.3, 0.8))));
  } else {
    const double x = r->uniform(0.0, 0.5 * L);
    it.boxes.push_back(
        makeBox(x, 0.0, h, x + r->uniform(0.2, 0.5 * L), D * 0.5, h + r->uniform(0.2, 0.5)));
  }
  return it;
}

// Places furniture in one space: inside its free rectangles (the cells less half a wall where
// there are walls), out of the keep-clear zones, apart from each other.
class Furnisher {
 public:
  Furnisher(const BuildingParams& p, const std::vector<PlanRect>& free_rects,
            std::vector<PlanRect> keep_clear, Rng* rng, PrimitiveScene* scene)
      : p_(p), free_(free_rects), keep_clear_(std::move(keep_clear)), rng_(rng), scene_(scene) {
    for (const PlanRect& f : free_) floor_m2_ += f.area_m2();
  }

  int placed() const { return placed_; }
  double longestSide() const {
    double m = 0.0;
    for (const PlanRect& f : free_) m = std::max(m, (f.hi_m - f.lo_m).maxCoeff());
    return m;
  }

  // Against a wall (back at a side of a free rectangle), up to `tries` positions.
  bool wall(const Item& it, int tries = 30) {
    for (int t = 0; t < tries; ++t) {
      const PlanRect& f = free_[rng_->below(static_cast<int>(free_.size()))];
      const int side = rng_->below(4);  // 0: y low, 1: x high, 2: y high, 3: x low
      const int along = side % 2 == 0 ? 0 : 1;
      const double span = f.hi_m[along] - f.lo_m[along];
      if (it.length > span) continue;
      const double s = snap(f.lo_m[along] + rng_->uniform(0.0, span - it.length), it.length,
                            f.lo_m[along], f.hi_m[along]);
      Eigen::Vector2d origin;
      int q;
      switch (side) {
        case 0:
          q = 0, origin = Eigen::Vector2d(s, f.lo_m.y());
          break;
        case 1:
          q = 1, origin = Eigen::Vector2d(f.hi_m.x(), s);
          break;
        case 2:
          q = 2, origin = Eigen::Vector2d(s + it.length, f.hi_m.y());
          break;
        default:
          q = 3, origin = Eigen::Vector2d(f.lo_m.x(), s + it.length);
          break;
      }
      if (tryPlace(it, q, origin)) return true;
    }
    return false;
  }

  // Free-standing, turned by a random quarter turn.
  bool free(const Item& it, int tries = 30) {
    for (int t = 0; t < tries; ++t) {
      const PlanRect& f = free_[rng_->below(static_cast<int>(free_.size()))];
      const int q = rng_->below(4);
      const PlanRect local =
          placedRect(Eigen::Vector2d::Zero(), Eigen::Vector2d(it.length, it.depth), q,
                     Eigen::Vector2d::Zero());
      const Eigen::Vector2d size = local.hi_m - local.lo_m;
      if (size.x() > f.hi_m.x() - f.lo_m.x() || size.y() > f.hi_m.y() - f.lo_m.y()) continue;
      Eigen::Vector2d lo;
      for (int k = 0; k < 2; ++k) {
        lo[k] = snap(rng_->uniform(f.lo_m[k], f.hi_m[k] - size[k]), size[k], f.lo_m[k], f.hi_m[k]);
      }
      if (tryPlace(it, q, lo - local.lo_m)) return true;
    }
    return false;
  }

  // Ceiling lamps, beams and ducts: above the doors, so they keep nobody out.
  void ceiling(int lamps, bool beam) {
    const double H = p_.height_m;
    for (int i = 0; i < lamps; ++i) {
      const PlanRect& f = free_[rng_->below(static_cast<int>(free_.size()))];
      const bool long_lamp = rng_->chance(0.5);
      const double a = long_lamp ? 1.2 : 0.6, b = long_lamp ? 0.3 : 0.6;
      const bool turn = rng_->chance(0.5);
      const double sx = turn ? b : a, sy = turn ? a : b;
      if (f.hi_m.x() - f.lo_m.x() < sx + 0.4 || f.hi_m.y() - f.lo_m.y() < sy + 0.4) continue;
      const double x = rng_->uniform(f.lo_m.x() + 0.2, f.hi_m.x() - sx - 0.2);
      const double y = rng_->uniform(f.lo_m.y() + 0.2, f.hi_m.y() - sy - 0.2);
      const double drop = rng_->uniform(0.12, 0.4);
      scene_->boxes.push_back(makeBox(x, y, H - drop - 0.06, x + sx, y + sy, H - drop));
    }
    if (beam) {
      const PlanRect& f = free_[rng_->below(static_cast<int>(free_.size()))];
      const Eigen::Vector2d size = f.hi_m - f.lo_m;
      const int across = size.x() < size.y() ? 0 : 1;  // the beam spans the shorter side
      const int o = 1 - across;
      const double w = rng_->uniform(0.25, 0.45);
      if (size[o] < w + 1.0) return;
      const double at = rng_->uniform(f.lo_m[o] + 0.5, f.hi_m[o] - w - 0.5);
      Box bx;
      bx.min_m[across] = f.lo_m[across];
      bx.max_m[across] = f.hi_m[across];
      bx.min_m[o] = at;
      bx.max_m[o] = at + w;
      bx.min_m[2] = H - rng_->uniform(0.3, 0.5);
      bx.max_m[2] = H;
      scene_->boxes.push_back(bx);
    }
  }

 private:
  // An item's start s (length len) between lo and hi, moved against lo or hi when nearer than
  // kSnapToWallM: furniture stands against a wall or clearly apart from it (no slivers of
  // surface a millimetre apart).
  static double snap(double s, double len, double lo, double hi) {
    if (s - lo < kSnapToWallM) return lo;
    if (hi - (s + len) < kSnapToWallM) return hi - len;
    return s;
  }

  bool tryPlace(const Item& it, int q, const Eigen::Vector2d& origin) {
    const PlanRect fp =
        placedRect(Eigen::Vector2d::Zero(), Eigen::Vector2d(it.length, it.depth), q, origin);
    bool inside = false;
    for (const PlanRect& f : free_) inside = inside || insideRect(fp, f);
    if (!inside) return false;
    if (covered_m2_ + fp.area_m2() > kMaxFurnitureCover * floor_m2_) return false;
    for (const PlanRect& k : keep_clear_) {
      if (overlaps(fp, k)) return false;
    }
    for (const auto& o : taken_) {
      if (overlaps(grown(fp, std::max(it.gap, o.second)), o.first)) return false;
    }
    for (const Box& b : it.boxes) {
      const PlanRect r = placedRect(b.min_m.head<2>(), b.max_m.head<2>(), q, origin);
      scene_->boxes.push_back(
          makeBox(r.lo_m.x(), r.lo_m.y(), b.min_m.z(), r.hi_m.x(), r.hi_m.y(), b.max_m.z()));
    }
    for (const Cylinder& c : it.cylinders) {
      Cylinder w = c;
      w.centre_m = place2(c.centre_m, q, origin);
      scene_->cylinders.push_back(w);
    }
    taken_.emplace_back(fp, it.gap);
    covered_m2_ += fp.area_m2();
    ++placed_;
    return true;
  }

  const BuildingParams& p_;
  std::vector<PlanRect> free_;
  std::vector<PlanRect> keep_clear_;
  Rng* rng_;
  PrimitiveScene* scene_;
  std::vector<std::pair<PlanRect, double>> taken_;
  double floor_m2_ = 0.0, covered_m2_ = 0.0;
  int placed_ = 0;
};

// The room kinds and what each holds (counts are upper bounds: what does not fit is dropped).
const char* const kRoomKinds[] = {"office",  "meeting", "storage",  "lounge",  "lab",
                                  "kitchen", "hall",    "workshop", "archive", "classroom"};

void furnishRoom(const std::string& kind, Furnisher* f, Rng* r, double H) {
  const double L = f->longestSide();
  auto times = [&](int lo, int hi, const std::function<void()>& fn) {
    for (int i = r->between(lo, hi); i > 0; --i) fn();
  };
  if (kind == "office") {
    times(2, 6, [&] { f->wall(desk(r, L)); });
    times(0, 2, [&] { f->wall(shelf(r, L, H)); });
    times(0, 1, [&] { f->wall(cabinet(r, L)); });
    times(0, 1, [&] { f->free(plant(r)); });
    times(0, 1, [&] { f->wall(whiteboard(r, L)); });
  } else if (kind == "meeting") {
    f->free(table(r, L));
    times(0, 2, [&] { f->wall(cabinet(r, L)); });
    times(1, 2, [&] { f->wall(whiteboard(r, L)); });
    times(0, 2, [&] { f->free(plant(r)); });
  } else if (kind == "storage") {
    times(3, 8, [&] { f->wall(shelf(r, L, H)); });
    times(1, 3, [&] { f->free(crates(r)); });
    times(0, 3, [&] { f->free(drums(r)); });
  } else if (kind == "lounge") {
    times(1, 3, [&] { f->wall(sofa(r, L)); });
    times(1, 3, [&] { f->free(roundTable(r)); });
    times(1, 3, [&] { f->free(plant(r)); });
    times(0, 1, [&] { f->wall(cabinet(r, L)); });
  } else if (kind == "lab") {
    times(1, 3, [&] { f->wall(counter(r, L, H)); });
    times(1, 2, [&] { f->free(machine(r, H)); });
    times(0, 1, [&] { f->free(column(r, H)); });
    times(0, 2, [&] { f->wall(shelf(r, L, H)); });
  } else if (kind == "kitchen") {
    times(1, 2, [&] { f->wall(counter(r, L, H)); });
    times(1, 2, [&] { f->free(roundTable(r)); });
    times(0, 2, [&] { f->wall(cabinet(r, L)); });
    times(0, 1, [&] { f->free(drums(r)); });
  } else if (kind == "hall") {
    times(2, 6, [&] { f->free(column(r, H)); });
    times(1, 2, [&] { f->wall(wallPartition(r, 0.4 * L, H)); });
    times(0, 2, [&] { f->free(crates(r)); });
    times(1, 3, [&] { f->free(plant(r)); });
    times(0, 2, [&] { f->wall(bench(r, L)); });
  } else if (kind == "workshop") {
    times(2, 4, [&] { f->free(machine(r, H)); });
    times(1, 3, [&] { f->free(drums(r)); });
    times(0, 2, [&] { f->free(crates(r)); });
    times(1, 2, [&] { f->wall(shelf(r, L, H)); });
  } else if (kind == "archive") {
    times(3, 6, [&] { f->free(shelf(r, L, H)); });
    times(1, 3, [&] { f->wall(cabinet(r, L)); });
    times(0, 1, [&] { f->wall(lockers(r, L)); });
  } else {  // classroom
    times(3, 8, [&] { f->free(desk(r, L)); });
    times(1, 2, [&] { f->wall(whiteboard(r, L)); });
    times(0, 1, [&] { f->wall(cabinet(r, L)); });
  }
}

void furnishCorridor(Furnisher* f, Rng* r, double H) {
  const double L = f->longestSide();
  auto times = [&](int lo, int hi, const std::function<void()>& fn) {
    for (int i = r->between(lo, hi); i > 0; --i) fn();
  };
  times(4, 9, [&] { f->wall(pilaster(r, H)); });
  times(3, 7, [&] { f->wall(bench(r, L)); });
  times(2, 6, [&] { f->wall(lockers(r, L)); });
  times(3, 7, [&] { f->wall(whiteboard(r, L)); });
  times(2, 5, [&] {
    Item it = plant(r);
    f->wall(it);
  });
}

// Free rectangles of a space: its cells less half a wall on every side inside the shell.
std::vector<PlanRect> freeRects(const BuildingSpace& s, const BuildingParams& p) {
  std::vector<PlanRect> out;
  const double t = 0.5 * p.wall_thickness_m;
  const Eigen::Vector2d size(p.width_m, p.length_m);
  for (const PlanRect& c : s.cells) {
    PlanRect f = c;
    for (int k = 0; k < 2; ++k) {
      if (f.lo_m[k] > 1e-7) f.lo_m[k] += t;
      if (f.hi_m[k] < size[k] - 1e-7) f.hi_m[k] -= t;
    }
    out.push_back(f);
  }
  return out;
}

// A rectangle across the line x = plane (normal_axis 0) or y = plane from s0 to s1 along it,
// depth d on either side.
PlanRect across(int normal_axis, double plane, double s0, double s1, double d) {
  PlanRect r;
  r.lo_m[normal_axis] = plane - d;
  r.hi_m[normal_axis] = plane + d;
  r.lo_m[1 - normal_axis] = s0;
  r.hi_m[1 - normal_axis] = s1;
  return r;
}

void furnish(const Plan& plan, const BuildingParams& p, Rng* rng, BuildingScene* b) {
  std::vector<PlanRect> keep;
  for (const BuildingDoor& d : plan.doors) {
    keep.push_back(
        across(d.normal_axis, d.plane_m, d.centre_m - 0.5 * d.width_m - kDoorKeepClearSideM,
               d.centre_m + 0.5 * d.width_m + kDoorKeepClearSideM, kDoorKeepClearDepthM));
  }
  for (const Boundary& bd : plan.boundaries) {
    const bool corridors = plan.cells[bd.cell_a].corridor && plan.cells[bd.cell_b].corridor;
    if (corridors) {
      keep.push_back(across(bd.normal_axis, bd.plane, bd.lo, bd.hi, kJunctionKeepClearDepthM));
    } else if (bd.kind == Boundary::kOpen) {
      keep.push_back(across(bd.normal_axis, bd.plane, bd.lo, bd.hi, kOpeningKeepClearDepthM));
    } else if (bd.kind == Boundary::kPartial) {
      keep.push_back(
          across(bd.normal_axis, bd.plane, bd.open_lo, bd.open_hi, kOpeningKeepClearDepthM));
    }
  }
  const int n_kinds = static_cast<int>(sizeof(kRoomKinds) / sizeof(kRoomKinds[0]));
  std::string previous;
  for (size_t i = 0; i < b->spaces.size(); ++i) {
    BuildingSpace& s = b->spaces[i];
    const std::vector<PlanRect> free_rects = freeRects(s, p);
    double area = 0.0;
    for (const PlanRect& f : free_rects) area += f.area_m2();
    Furnisher f(p, free_rects, keep, rng, &b->primitives);
    if (s.corridor) {
      furnishCorridor(&f, rng, p.height_m);
      f.ceiling(static_cast<int>(area / 8.0), false);
      for (int k = rng->between(2, 4); k > 0; --k) f.ceiling(0, true);
      continue;
    }
    // A kind for the room: halls only when large, classrooms not when small; never the same
    // kind twice in a row.
    for (int tries = 0; tries < 50; ++tries) {
      s.kind = kRoomKinds[rng->below(n_kinds)];
      if (s.kind == previous) continue;
      if (s.kind == "hall" && area < 70.0) continue;
      if (s.kind == "classroom" && area < 35.0) continue;
      break;
    }
    previous = s.kind;
    furnishRoom(s.kind, &f, rng, p.height_m);
    f.ceiling(rng->between(1, std::max(1, static_cast<int>(area / 10.0))), rng->chance(0.35));
  }
}

}  // namespace

std::string BuildingParams::validate() const {
  if (width_m < 30.0 || length_m < 30.0) return "width_m and length_m must be at least 30";
  if (!(height_m >= 2.5 && height_m <= 6.0)) return "height_m must be in [2.5, 6]";
  if (room_count < 4) return "room_count must be at least 4";
  if (merged_rooms < 0 || merged_rooms > room_count / 2)
    return "merged_rooms must be in [0, room_count / 2]";
  if (extra_doors < 0) return "extra_doors must be >= 0";
  if (!(wall_thickness_m > 0.02 && wall_thickness_m < 0.5))
    return "wall_thickness_m must be in (0.02, 0.5)";
  if (!(door_min_width_m >= 0.8 && door_max_width_m >= door_min_width_m &&
        door_max_width_m <= 2.0)) {
    return "door widths must satisfy 0.8 <= min <= max <= 2";
  }
  if (!(door_height_m >= 1.9 && door_height_m < height_m - 0.1))
    return "door_height_m must be in [1.9, height_m - 0.1)";
  if (!(corridor_min_width_m >= 1.5 && corridor_max_width_m >= corridor_min_width_m &&
        corridor_max_width_m <= 5.0)) {
    return "corridor widths must satisfy 1.5 <= min <= max <= 5";
  }
  if (!(min_room_side_m >= 2.5 && min_room_side_m <= 10.0))
    return "min_room_side_m must be in [2.5, 10]";
  return "";
}

Eigen::Vector2d BuildingDoor::centre2d() const {
  return normal_axis == 0 ? Eigen::Vector2d(plane_m, centre_m) : Eigen::Vector2d(centre_m, plane_m);
}

int BuildingScene::roomCount() const {
  return static_cast<int>(std::count_if(spaces.begin(), spaces.end(),
                                        [](const BuildingSpace& s) { return !s.corridor; }));
}

int BuildingScene::spaceAt(const Eigen::Vector2d& p_m) const {
  for (size_t i = 0; i < spaces.size(); ++i) {
    for (const PlanRect& c : spaces[i].cells) {
      if (c.contains(p_m)) return static_cast<int>(i);
    }
  }
  return -1;
}

BuildingScene makeBuilding(const BuildingParams& params) {
  const std::string why = params.validate();
  if (!why.empty()) throw std::invalid_argument("building parameters: " + why);
  Plan plan;
  bool ok = false;
  uint64_t draw = 0;
  for (int attempt = 0; attempt < kMaxAttempts && !ok; ++attempt) {
    draw = params.seed * 0x9e3779b97f4a7c15ull + static_cast<uint64_t>(attempt);
    Rng rng(draw);
    ok = makePlan(params, &rng, &plan);
  }
  if (!ok) {
    throw std::runtime_error("makeBuilding: no floor plan with " +
                             std::to_string(params.room_count) + " rooms and " +
                             std::to_string(params.extra_doors) +
                             " extra doors in the area (fewer rooms, or a larger building)");
  }
  BuildingScene b;
  b.params = params;
  b.spaces = plan.spaces;
  b.doors = plan.doors;
  b.primitives.room = makeBox(0.0, 0.0, 0.0, params.width_m, params.length_m, params.height_m);
  buildWalls(plan, params, &b.primitives);
  b.wall_box_count = b.primitives.boxes.size();
  Rng rng(draw ^ 0x5bd1e9955bd1e995ull);  // furniture: its own stream
  furnish(plan, params, &rng, &b);
  return b;
}

Mesh meshFromBuilding(const BuildingScene& building) {
  return visibleMeshFromScene(building.primitives, 24);
}

GmmMap tileBuilding(const BuildingScene& building, double spacing_m, double normal_sigma_m) {
  return tileVisibleScene(building.primitives, spacing_m, normal_sigma_m);
}

bool insideSolid(const PrimitiveScene& scene, const Eigen::Vector3d& p, double margin_m) {
  const Box& room = scene.room;
  if (((p - room.min_m).array() < margin_m).any() || ((room.max_m - p).array() < margin_m).any()) {
    return true;
  }
  for (const Box& b : scene.boxes) {
    if (((p - b.min_m).array() > -margin_m).all() && ((b.max_m - p).array() > -margin_m).all()) {
      return true;
    }
  }
  for (const Cylinder& c : scene.cylinders) {
    if (p.z() < c.z_min_m - margin_m || p.z() > c.z_max_m + margin_m) continue;
    if ((p.head<2>() - c.centre_m).norm() < c.radius_m + margin_m) return true;
  }
  return false;
}

}  // namespace sim
}  // namespace gmm_mcl
