#include "gmm_mcl/sim/building_walk.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <queue>
#include <stdexcept>
#include <utility>

#include "gmm_mcl/filter/pose.h"
#include "gmm_mcl/sim/box_scene.h"
#include "gmm_mcl/sim/uniform_rng.h"

namespace gmm_mcl {
namespace sim {
namespace {

constexpr double kCellM = 0.05;          // planning grid
constexpr double kHeadroomM = 0.3;       // obstacles: anything lower than max height + this
constexpr double kPlanMarginM = 0.1;     // A* cells keep clearance + this ...
constexpr double kSmoothMarginM = 0.05;  // ... smoothing clearance + this (5 cm samples between)
constexpr double kPreferClearM = 1.0;    // steps closer than this to an obstacle cost more
constexpr double kNearCost = 2.0;        // up to 1 + this times the length right at the limit
constexpr double kTargetClearM = 0.6;    // a stop in a room keeps this from everything
constexpr double kMinLegM = 3.0;         // a stop is at least this far from the previous one
constexpr int kSmoothIterations = 250;
constexpr double kSmoothStepM = 0.1;
constexpr double kSampleM = 0.05;      // leg samples
constexpr double kStopSpeedMps = 0.1;  // speed at a stop (eased in and out at kLongAccel)
constexpr double kLongAccelMps2 = 0.5;
constexpr double kTurnPauseS = 0.4;  // added to each turn on the spot
constexpr double kLookAroundChance = 0.5;
constexpr int kRoomsDrawn = 3;            // the next room: the nearest of this many drawn
constexpr double kStopChance = 0.3;       // stopping at a room's point where no turn forces it
constexpr double kMaxPassTurnCos = 0.2;   // turns sharper than about 80 deg stop first
constexpr size_t kTurnProbeCells = 20;    // the turn at a stop: directions over about 1 m
constexpr double kYawSmoothFrames = 4.0;  // Gaussian sigma over the frames' yaw
constexpr double kInf = std::numeric_limits<double>::infinity();

// Conservative horizontal clearance on a grid over the floor plan: the distance from each cell
// centre to the nearest cell that an obstacle's footprint touches, less half a cell diagonal,
// and never more than the distance to the shell.
class ClearanceGrid {
 public:
  ClearanceGrid(const BuildingScene& b, double obstacle_top_m) {
    const Box& shell = b.bounds();
    lo_ = shell.min_m.head<2>();
    hi_ = shell.max_m.head<2>();
    nx_ = static_cast<int>(std::ceil((hi_.x() - lo_.x()) / kCellM));
    ny_ = static_cast<int>(std::ceil((hi_.y() - lo_.y()) / kCellM));
    std::vector<char> occupied(size(), 0);
    auto clampX = [&](double v) { return std::min(nx_ - 1, std::max(0, static_cast<int>(v))); };
    auto clampY = [&](double v) { return std::min(ny_ - 1, std::max(0, static_cast<int>(v))); };
    for (const Box& box : b.primitives.boxes) {
      if (!(box.min_m.z() < obstacle_top_m)) continue;
      const int i0 = clampX(std::floor((box.min_m.x() - lo_.x()) / kCellM));
      const int i1 = clampX(std::ceil((box.max_m.x() - lo_.x()) / kCellM) - 1);
      const int j0 = clampY(std::floor((box.min_m.y() - lo_.y()) / kCellM));
      const int j1 = clampY(std::ceil((box.max_m.y() - lo_.y()) / kCellM) - 1);
      for (int j = j0; j <= j1; ++j) {
        for (int i = i0; i <= i1; ++i) occupied[index(i, j)] = 1;
      }
    }
    for (const Cylinder& c : b.primitives.cylinders) {
      if (!(c.z_min_m < obstacle_top_m)) continue;
      const int i0 = clampX(std::floor((c.centre_m.x() - c.radius_m - lo_.x()) / kCellM));
      const int i1 = clampX(std::floor((c.centre_m.x() + c.radius_m - lo_.x()) / kCellM));
      const int j0 = clampY(std::floor((c.centre_m.y() - c.radius_m - lo_.y()) / kCellM));
      const int j1 = clampY(std::floor((c.centre_m.y() + c.radius_m - lo_.y()) / kCellM));
      for (int j = j0; j <= j1; ++j) {
        for (int i = i0; i <= i1; ++i) {
          const Eigen::Vector2d d =
              ((centre(i, j) - c.centre_m).cwiseAbs().array() - 0.5 * kCellM).max(0.0).matrix();
          if (d.norm() < c.radius_m) occupied[index(i, j)] = 1;
        }
      }
    }
    // Squared distance transform in cells (Felzenszwalb and Huttenlocher's lower envelope of
    // parabolas), columns then rows.
    const double big = 1e12;
    std::vector<double> d2(size());
    for (size_t k = 0; k < d2.size(); ++k) d2[k] = occupied[k] ? 0.0 : big;
    std::vector<double> f, out;
    for (int i = 0; i < nx_; ++i) {
      f.resize(ny_);
      for (int j = 0; j < ny_; ++j) f[j] = d2[index(i, j)];
      transform1d(f, &out);
      for (int j = 0; j < ny_; ++j) d2[index(i, j)] = out[j];
    }
    for (int j = 0; j < ny_; ++j) {
      f.resize(nx_);
      for (int i = 0; i < nx_; ++i) f[i] = d2[index(i, j)];
      transform1d(f, &out);
      for (int i = 0; i < nx_; ++i) d2[index(i, j)] = out[i];
    }
    clear_.resize(size());
    const double half_diagonal = 0.5 * std::sqrt(2.0) * kCellM;
    for (int j = 0; j < ny_; ++j) {
      for (int i = 0; i < nx_; ++i) {
        const Eigen::Vector2d c = centre(i, j);
        const double shell = std::min((c - lo_).minCoeff(), (hi_ - c).minCoeff());
        const size_t k = index(i, j);
        const double obstacle = d2[k] >= big ? kInf : std::sqrt(d2[k]) * kCellM - half_diagonal;
        clear_[k] = static_cast<float>(std::min(shell, obstacle));
      }
    }
  }

  int nx() const { return nx_; }
  int ny() const { return ny_; }
  size_t size() const { return static_cast<size_t>(nx_) * ny_; }
  size_t index(int i, int j) const { return static_cast<size_t>(j) * nx_ + i; }
  Eigen::Vector2d centre(int i, int j) const {
    return lo_ + kCellM * Eigen::Vector2d(i + 0.5, j + 0.5);
  }
  Eigen::Vector2d centre(size_t k) const {
    return centre(static_cast<int>(k % nx_), static_cast<int>(k / nx_));
  }
  double clearAt(size_t k) const { return clear_[k]; }
  bool cellOf(const Eigen::Vector2d& p, size_t* k) const {
    const int i = static_cast<int>(std::floor((p.x() - lo_.x()) / kCellM));
    const int j = static_cast<int>(std::floor((p.y() - lo_.y()) / kCellM));
    if (i < 0 || j < 0 || i >= nx_ || j >= ny_) return false;
    *k = index(i, j);
    return true;
  }
  // A lower bound of the clearance at any point: the best of the four nearest cell centres'
  // values less the distance to them (the clearance changes no faster than the position).
  double lowerBound(const Eigen::Vector2d& p) const {
    const double fx = (p.x() - lo_.x()) / kCellM - 0.5, fy = (p.y() - lo_.y()) / kCellM - 0.5;
    const int i0 = static_cast<int>(std::floor(fx)), j0 = static_cast<int>(std::floor(fy));
    double best = -kInf;
    for (int dj = 0; dj < 2; ++dj) {
      for (int di = 0; di < 2; ++di) {
        const int i = i0 + di, j = j0 + dj;
        if (i < 0 || j < 0 || i >= nx_ || j >= ny_) continue;
        best = std::max(best, clear_[index(i, j)] - (p - centre(i, j)).norm());
      }
    }
    return best;
  }

 private:
  static void transform1d(const std::vector<double>& f, std::vector<double>* d) {
    const int n = static_cast<int>(f.size());
    d->assign(n, 0.0);
    std::vector<int> v(n);
    std::vector<double> z(n + 1);
    int k = 0;
    v[0] = 0;
    z[0] = -kInf;
    z[1] = kInf;
    auto cross = [&](int q, int r) {
      return ((f[q] + double(q) * q) - (f[r] + double(r) * r)) / (2.0 * q - 2.0 * r);
    };
    for (int q = 1; q < n; ++q) {
      double s = cross(q, v[k]);
      while (s <= z[k]) s = cross(q, v[--k]);  // z[0] = -inf ends it
      ++k;
      v[k] = q;
      z[k] = s;
      z[k + 1] = kInf;
    }
    k = 0;
    for (int q = 0; q < n; ++q) {
      while (z[k + 1] < q) ++k;
      (*d)[q] = double(q - v[k]) * (q - v[k]) + f[v[k]];
    }
  }

  Eigen::Vector2d lo_, hi_;
  int nx_ = 0, ny_ = 0;
  std::vector<float> clear_;
};

// A* over the cells with at least min_clear_m clearance, 8-connected, each step's length
// weighted up near obstacles. The path's cell centres from start to goal; false when none.
class PathPlanner {
 public:
  explicit PathPlanner(const ClearanceGrid& grid)
      : grid_(grid), cost_(grid.size(), kInf), parent_(grid.size(), -1), closed_(grid.size(), 0) {}

  bool plan(size_t start, size_t goal, double min_clear_m, std::vector<Eigen::Vector2d>* path) {
    for (size_t k : touched_) {
      cost_[k] = kInf;
      parent_[k] = -1;
      closed_[k] = 0;
    }
    touched_.clear();
    path->clear();
    if (grid_.clearAt(start) < min_clear_m || grid_.clearAt(goal) < min_clear_m) return false;
    const Eigen::Vector2d target = grid_.centre(goal);
    using Entry = std::pair<double, size_t>;
    std::priority_queue<Entry, std::vector<Entry>, std::greater<Entry>> open;
    cost_[start] = 0.0;
    touched_.push_back(start);
    open.emplace((grid_.centre(start) - target).norm(), start);
    const int nx = grid_.nx(), ny = grid_.ny();
    while (!open.empty()) {
      const size_t k = open.top().second;
      open.pop();
      if (closed_[k]) continue;
      closed_[k] = 1;
      if (k == goal) break;
      const int i = static_cast<int>(k % nx), j = static_cast<int>(k / nx);
      for (int dj = -1; dj <= 1; ++dj) {
        for (int di = -1; di <= 1; ++di) {
          if ((di == 0 && dj == 0) || i + di < 0 || j + dj < 0 || i + di >= nx || j + dj >= ny) {
            continue;
          }
          const size_t n = grid_.index(i + di, j + dj);
          const double clear = grid_.clearAt(n);
          if (closed_[n] || clear < min_clear_m) continue;
          const double len = (di != 0 && dj != 0 ? std::sqrt(2.0) : 1.0) * kCellM;
          const double near = std::max(0.0, kPreferClearM - clear) / kPreferClearM;
          const double c = cost_[k] + len * (1.0 + kNearCost * near);
          if (c >= cost_[n]) continue;
          if (cost_[n] == kInf) touched_.push_back(n);
          cost_[n] = c;
          parent_[n] = static_cast<long>(k);
          open.emplace(c + (grid_.centre(n) - target).norm(), n);
        }
      }
    }
    if (!closed_[goal]) return false;
    for (long k = static_cast<long>(goal); k >= 0; k = parent_[k]) {
      path->push_back(grid_.centre(static_cast<size_t>(k)));
    }
    std::reverse(path->begin(), path->end());
    return true;
  }

 private:
  const ClearanceGrid& grid_;
  std::vector<double> cost_;
  std::vector<long> parent_;
  std::vector<char> closed_;
  std::vector<size_t> touched_;
};

// Points every `step` along a polyline, both ends kept.
std::vector<Eigen::Vector2d> resample(const std::vector<Eigen::Vector2d>& pts, double step) {
  std::vector<double> s(pts.size(), 0.0);
  for (size_t i = 1; i < pts.size(); ++i) s[i] = s[i - 1] + (pts[i] - pts[i - 1]).norm();
  const double total = s.back();
  const int n = std::max(1, static_cast<int>(std::ceil(total / step - 1e-9)));
  std::vector<Eigen::Vector2d> out;
  size_t seg = 0;
  for (int k = 0; k <= n; ++k) {
    const double at = total * k / n;
    while (seg + 2 < pts.size() && s[seg + 1] < at) ++seg;
    const double len = s[seg + 1] - s[seg];
    const double a = len > 0.0 ? std::min(1.0, std::max(0.0, (at - s[seg]) / len)) : 0.0;
    out.push_back(pts[seg] + a * (pts[seg + 1] - pts[seg]));
  }
  return out;
}

// Rounds a planned path: repeated moves of each inner point halfway towards the middle of its
// neighbours, each kept only where the clearance bound allows.
std::vector<Eigen::Vector2d> smoothPath(const ClearanceGrid& grid,
                                        const std::vector<Eigen::Vector2d>& path,
                                        double min_clear_m) {
  if (path.size() < 2) return path;
  std::vector<Eigen::Vector2d> p = resample(path, kSmoothStepM);
  for (int it = 0; it < kSmoothIterations; ++it) {
    for (size_t i = 1; i + 1 < p.size(); ++i) {
      const Eigen::Vector2d q = p[i] + 0.5 * (0.5 * (p[i - 1] + p[i + 1]) - p[i]);
      if (grid.lowerBound(q) >= min_clear_m) p[i] = q;
    }
  }
  return resample(p, kSampleM);
}

// A moment of the flight: position and heading (unwrapped).
struct Knot {
  double t;
  Eigen::Vector2d p;
  double yaw;
};

double wrapPi(double a) { return std::atan2(std::sin(a), std::cos(a)); }

double smoothstep(double u) { return u * u * (3.0 - 2.0 * u); }

// Times a smoothed leg: the heading along the path, the speed limited by the cruise speed, the
// turn (lateral acceleration) and easing from and to a stop, then acceleration-limited both ways.
void addLeg(const std::vector<Eigen::Vector2d>& pts, const BuildingWalkParams& wp,
            std::vector<Knot>* knots) {
  const size_t n = pts.size();
  std::vector<double> s(n, 0.0), yaw(n), v(n);
  for (size_t i = 1; i < n; ++i) s[i] = s[i - 1] + (pts[i] - pts[i - 1]).norm();
  const int w = 4;  // heading from points +-20 cm apart
  for (size_t i = 0; i < n; ++i) {
    const size_t a = i >= static_cast<size_t>(w) ? i - w : 0, b = std::min(n - 1, i + w);
    const Eigen::Vector2d d = pts[b] - pts[a];
    yaw[i] = std::atan2(d.y(), d.x());
    if (i > 0) yaw[i] = yaw[i - 1] + wrapPi(yaw[i] - yaw[i - 1]);
  }
  for (size_t i = 0; i < n; ++i) {
    const size_t a = i >= static_cast<size_t>(w) ? i - w : 0, b = std::min(n - 1, i + w);
    const double ds = s[b] - s[a];
    const double kappa = ds > 1e-6 ? std::abs(yaw[b] - yaw[a]) / ds : 0.0;
    double vi = wp.max_speed_mps;
    if (kappa > 1e-6) vi = std::min(vi, std::sqrt(wp.lateral_accel_mps2 / kappa));
    v[i] = std::max(kStopSpeedMps, vi);
  }
  v.front() = v.back() = kStopSpeedMps;
  for (size_t i = 1; i < n; ++i) {
    v[i] =
        std::min(v[i], std::sqrt(v[i - 1] * v[i - 1] + 2.0 * kLongAccelMps2 * (s[i] - s[i - 1])));
  }
  for (size_t i = n - 1; i-- > 0;) {
    v[i] =
        std::min(v[i], std::sqrt(v[i + 1] * v[i + 1] + 2.0 * kLongAccelMps2 * (s[i + 1] - s[i])));
  }
  double t = knots->empty() ? 0.0 : knots->back().t;
  double yaw_offset = 0.0;
  if (!knots->empty()) {  // continue the unwrapped heading
    yaw_offset = knots->back().yaw + wrapPi(yaw[0] - knots->back().yaw) - yaw[0];
  }
  for (size_t i = 0; i < n; ++i) {
    if (i > 0) t += (s[i] - s[i - 1]) / (0.5 * (v[i] + v[i - 1]));
    if (i == 0 && !knots->empty()) continue;  // the stop's last knot is this point
    knots->push_back({t, pts[i], yaw[i] + yaw_offset});
  }
}

// A stop: turning on the spot through the given headings (unwrapped), smoothly.
void addTurn(const std::vector<double>& headings, const BuildingWalkParams& wp,
             std::vector<Knot>* knots) {
  const Knot last = knots->back();
  double t = last.t;
  const double dt = 0.5 / wp.rate_hz;
  for (size_t k = 1; k < headings.size(); ++k) {
    const double a = headings[k - 1], b = headings[k];
    const double duration = kTurnPauseS + std::abs(b - a) / wp.turn_rate_radps;
    const int steps = std::max(1, static_cast<int>(std::ceil(duration / dt)));
    for (int i = 1; i <= steps; ++i) {
      const double u = static_cast<double>(i) / steps;
      knots->push_back({t + u * duration, last.p, a + (b - a) * smoothstep(u)});
    }
    t += duration;
  }
}

// The first heading of a leg.
double legHeading(const std::vector<Eigen::Vector2d>& pts) {
  const Eigen::Vector2d d = pts[std::min<size_t>(pts.size() - 1, 4)] - pts[0];
  return std::atan2(d.y(), d.x());
}

}  // namespace

std::string BuildingWalkParams::validate() const {
  if (frames < 1) return "frames must be >= 1";
  if (!(rate_hz > 0.0 && rate_hz <= 1000.0)) return "rate_hz must be in (0, 1000]";
  if (!(max_speed_mps >= 0.2 && max_speed_mps <= 3.0)) return "max_speed_mps must be in [0.2, 3]";
  if (!(lateral_accel_mps2 > 0.0)) return "lateral_accel_mps2 must be > 0";
  if (!(min_height_m >= 0.3 && max_height_m >= min_height_m)) {
    return "heights must satisfy 0.3 <= min_height_m <= max_height_m";
  }
  if (!(clearance_m >= 0.1 && clearance_m <= 0.45)) return "clearance_m must be in [0.1, 0.45]";
  if (!(turn_rate_radps > 0.0)) return "turn_rate_radps must be > 0";
  if (!(sweep_interval_s > 0.0)) return "sweep_interval_s must be > 0";
  if (!(sweep_amplitude_rad >= 0.0 && sweep_amplitude_rad <= 1.5))
    return "sweep_amplitude_rad must be in [0, 1.5]";
  return "";
}

BuildingWalk makeBuildingWalk(const BuildingScene& building, const BuildingWalkParams& wp) {
  const std::string why = wp.validate();
  if (!why.empty()) throw std::invalid_argument("building walk: " + why);
  const double obstacle_top = wp.max_height_m + kHeadroomM;
  if (building.params.door_height_m < obstacle_top ||
      building.params.height_m < obstacle_top + 0.2) {
    throw std::invalid_argument("building walk: the doors and ceiling must clear max_height_m + " +
                                std::to_string(kHeadroomM) + " m");
  }
  // Three streams (route; sweeps; height and attitude), so that the sweeps and the height of the
  // first frames do not depend on how long the route grows.
  const uint64_t base_seed = wp.seed * 0xbf58476d1ce4e5b9ull + 0x94d049bb133111ebull;
  UniformRng rng(base_seed), sweep_rng(base_seed ^ 0x2545f4914f6cdd1dull),
      motion_rng(base_seed ^ 0x9e3779b97f4a7c15ull);
  const ClearanceGrid grid(building, obstacle_top);
  PathPlanner planner(grid);
  const double plan_clear = wp.clearance_m + kPlanMarginM;

  // The door graph between spaces.
  const int n_spaces = static_cast<int>(building.spaces.size());
  std::vector<std::vector<int>> next_to(n_spaces);
  for (const BuildingDoor& d : building.doors) {
    next_to[d.space_a].push_back(d.space_b);
    next_to[d.space_b].push_back(d.space_a);
  }
  auto hops = [&](int from) {
    std::vector<int> h(n_spaces, -1);
    std::vector<int> queue{from};
    h[from] = 0;
    for (size_t q = 0; q < queue.size(); ++q) {
      for (int n : next_to[queue[q]]) {
        if (h[n] < 0) {
          h[n] = h[queue[q]] + 1;
          queue.push_back(n);
        }
      }
    }
    return h;
  };
  // A cell in the space with kTargetClearM clearance, drawn at random; false when none.
  auto stopIn = [&](int space, const Eigen::Vector2d* away_from, size_t* cell) {
    const BuildingSpace& s = building.spaces[space];
    for (int tries = 0; tries < 300; ++tries) {
      const PlanRect& r = s.cells[rng.below(static_cast<int>(s.cells.size()))];
      const Eigen::Vector2d p(rng.uniform(r.lo_m.x(), r.hi_m.x()),
                              rng.uniform(r.lo_m.y(), r.hi_m.y()));
      size_t k;
      if (!grid.cellOf(p, &k) || grid.clearAt(k) < kTargetClearM) continue;
      if (away_from && (grid.centre(k) - *away_from).norm() < kMinLegM) continue;
      *cell = k;
      return true;
    }
    return false;
  };

  std::vector<int> rooms;
  for (int i = 0; i < n_spaces; ++i) {
    if (!building.spaces[i].corridor) rooms.push_back(i);
  }
  if (rooms.empty()) throw std::runtime_error("building walk: the building has no rooms");
  int space = -1;
  size_t at = 0;
  for (int tries = 0; tries < 100 && space < 0; ++tries) {
    const int s = rooms[rng.below(static_cast<int>(rooms.size()))];
    if (stopIn(s, nullptr, &at)) space = s;
  }
  if (space < 0) throw std::runtime_error("building walk: no free start in any room");

  const double duration_s = (wp.frames - 1) / wp.rate_hz;
  std::vector<Knot> knots;
  knots.push_back({0.0, grid.centre(at), 0.0});
  std::vector<int> recent{space};
  // Legs join into runs, flown without stopping, where the turn at the stop between them is
  // gentle; a run ends in a stop, where the drone turns on the spot (perhaps looking around
  // first) towards the next run.
  bool first_run = true;
  std::vector<Eigen::Vector2d> run;
  double run_m = 0.0;
  auto flyRun = [&] {
    const std::vector<Eigen::Vector2d> leg = smoothPath(grid, run, wp.clearance_m + kSmoothMarginM);
    const double out = legHeading(leg);
    if (first_run) {
      knots.back().yaw = out;
    } else {
      const double in = knots.back().yaw;
      const double target = in + wrapPi(out - in);
      std::vector<double> headings{in};
      if (rng.chance(kLookAroundChance)) {
        const double side = target >= in ? -1.0 : 1.0;  // look the other way first
        headings.push_back(in + side * rng.uniform(0.5, 1.2));
      }
      headings.push_back(target);
      addTurn(headings, wp, &knots);
    }
    first_run = false;
    addLeg(leg, wp, &knots);
    run.clear();
    run_m = 0.0;
  };
  while (knots.back().t + run_m / wp.max_speed_mps < duration_s + 1.0) {
    // The next room: one or two doors away (a corridor counts as one; next door three times as
    // likely), not among the last few.
    const std::vector<int> h = hops(space);
    std::vector<int> options, fallback;
    for (int r : rooms) {
      if (r == space || h[r] < 0) continue;
      const bool is_recent = std::find(recent.begin(), recent.end(), r) != recent.end();
      (h[r] <= 2 && !is_recent ? options : fallback).push_back(r);
      if (h[r] == 1 && !is_recent) options.insert(options.end(), 2, r);
    }
    if (options.empty()) options = fallback;
    if (options.empty()) throw std::runtime_error("building walk: no other room is reachable");
    // Of a few rooms drawn, the nearest by the path (more rooms in a sequence of a given length).
    std::vector<Eigen::Vector2d> path, candidate;
    int next = -1;
    size_t goal = 0;
    double best_m = kInf;
    for (int drawn = 0, tries = 0; drawn < kRoomsDrawn && tries < 12; ++tries) {
      const int r = options[rng.below(static_cast<int>(options.size()))];
      const Eigen::Vector2d from = grid.centre(at);
      size_t cell;
      if (!stopIn(r, &from, &cell) || !planner.plan(at, cell, plan_clear, &candidate)) continue;
      ++drawn;
      double len = 0.0;
      for (size_t i = 1; i < candidate.size(); ++i) len += (candidate[i] - candidate[i - 1]).norm();
      if (len < best_m) {
        best_m = len;
        next = r;
        goal = cell;
        path.swap(candidate);
      }
    }
    at = goal;
    if (next < 0) throw std::runtime_error("building walk: no path to the next room");
    if (!run.empty()) {
      const size_t m = std::min<size_t>(kTurnProbeCells, std::min(run.size(), path.size()) - 1);
      const Eigen::Vector2d in = run.back() - run[run.size() - 1 - m], out = path[m] - path[0];
      const double cos_turn = in.dot(out) / std::max(1e-9, in.norm() * out.norm());
      if (cos_turn < kMaxPassTurnCos || rng.chance(kStopChance)) flyRun();
    }
    run.insert(run.end(), run.empty() ? path.begin() : path.begin() + 1, path.end());
    for (size_t i = 1; i < path.size(); ++i) run_m += (path[i] - path[i - 1]).norm();
    space = next;
    recent.push_back(next);
    if (recent.size() > 3) recent.erase(recent.begin());
  }
  if (!run.empty()) flyRun();

  // Yaw sweeps: look to one side and the other and back, over 6-8 s (on top of whatever the
  // drone does then: flying, or turning at a stop).
  struct Sweep {
    double t0, duration, amplitude;
  };
  std::vector<Sweep> sweeps;
  for (double t = sweep_rng.uniform(3.0, wp.sweep_interval_s); t < duration_s;
       t += wp.sweep_interval_s * sweep_rng.uniform(0.5, 1.5)) {
    Sweep sw{t, sweep_rng.uniform(6.0, 8.0),
             wp.sweep_amplitude_rad * sweep_rng.uniform(0.6, 1.0) *
                 (sweep_rng.chance(0.5) ? 1.0 : -1.0)};
    sweeps.push_back(sw);
    t += sw.duration;
  }
  // Height and the small roll and pitch of a flying drone: slow sines of random phase.
  const double mid = 0.5 * (wp.min_height_m + wp.max_height_m);
  const double amp = 0.5 * (wp.max_height_m - wp.min_height_m);
  const double ph1 = motion_rng.uniform(0.0, 2.0 * M_PI), ph2 = motion_rng.uniform(0.0, 2.0 * M_PI);
  const double ph3 = motion_rng.uniform(0.0, 2.0 * M_PI), ph4 = motion_rng.uniform(0.0, 2.0 * M_PI);

  BuildingWalk walk;
  std::vector<Eigen::Vector2d> xy(wp.frames);
  std::vector<double> yaw(wp.frames);
  size_t k = 0;
  for (int f = 0; f < wp.frames; ++f) {
    const double t = f / wp.rate_hz;
    while (k + 2 < knots.size() && knots[k + 1].t <= t) ++k;
    const Knot &a = knots[k], &b = knots[k + 1];
    const double u = b.t > a.t ? std::min(1.0, std::max(0.0, (t - a.t) / (b.t - a.t))) : 0.0;
    xy[f] = a.p + u * (b.p - a.p);
    yaw[f] = a.yaw + u * (b.yaw - a.yaw);
    for (const Sweep& sw : sweeps) {
      const double s = (t - sw.t0) / sw.duration;
      if (s > 0.0 && s < 1.0)
        yaw[f] += sw.amplitude * std::sin(2.0 * M_PI * s) * std::sin(M_PI * s);
    }
    walk.stamps_s.push_back(t);
  }
  // A little smoothing of the heading (the path's heading carries the grid's small kinks).
  std::vector<double> smooth_yaw(wp.frames);
  const int r = static_cast<int>(std::ceil(3.0 * kYawSmoothFrames));
  for (int f = 0; f < wp.frames; ++f) {
    double sum = 0.0, wsum = 0.0;
    for (int d = -r; d <= r; ++d) {
      const int g = std::min(wp.frames - 1, std::max(0, f + d));
      const double w = std::exp(-0.5 * d * d / (kYawSmoothFrames * kYawSmoothFrames));
      sum += w * yaw[g];
      wsum += w;
    }
    smooth_yaw[f] = sum / wsum;
  }
  const Eigen::Isometry3d T_base_cam = defaultBaseToCamera();
  for (int f = 0; f < wp.frames; ++f) {
    const double t = walk.stamps_s[f];
    const double z = mid + amp * (0.6 * std::sin(2.0 * M_PI * t / 11.0 + ph1) +
                                  0.3 * std::sin(2.0 * M_PI * t / 4.3 + ph2));
    const double roll = 0.03 * std::sin(1.1 * t + ph3), pitch = 0.04 * std::sin(0.9 * t + ph4);
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.translation() = Eigen::Vector3d(xy[f].x(), xy[f].y(), z);
    T.linear() = rotationFromRpy(roll, pitch, wrapPi(smooth_yaw[f]));
    walk.T_world_base.push_back(T);
    walk.T_world_cam.push_back(T * T_base_cam);
    if (grid.lowerBound(xy[f]) < wp.clearance_m - 1e-9) {
      throw std::logic_error("building walk: frame " + std::to_string(f) +
                             " is closer to an obstacle than the clearance");
    }
    if (f > 0) walk.length_m += (xy[f] - xy[f - 1]).norm();
    const int s = building.spaceAt(xy[f]);
    if (s >= 0 && (walk.spaces.empty() || walk.spaces.back() != s)) walk.spaces.push_back(s);
  }
  return walk;
}

}  // namespace sim
}  // namespace gmm_mcl
