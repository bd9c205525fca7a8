#include "gmm_mcl/ros/frame_sets.h"

#include <algorithm>
#include <cmath>
#include <utility>

namespace gmm_mcl {
namespace {
// Frames kept per camera while they wait for a set (a camera faster than the lead).
constexpr size_t kKeptFrames = 8;
// A stamp this much before the newest seen is a jump back (a looped bag), as DepthInput's.
constexpr double kJumpBackS = 1.0;
double stampS(const CameraFrame& f) { return f.header.stamp.toSec(); }
}  // namespace

FrameSets::FrameSets(int cameras, const FrameSetParams& params)
    : params_(params), cams_(static_cast<size_t>(std::max(cameras, 1))) {}

bool FrameSets::delivers(int camera, double stamp_s) const {
  const double last = cams_[camera].stats.last_stamp_s;
  return last >= 0.0 && last >= stamp_s - params_.timeout_s;
}

int FrameSets::leadFor(double stamp_s) const {
  for (int i = 0; i < cameras(); ++i) {
    if (delivers(i, stamp_s)) return i;
  }
  return -1;
}

void FrameSets::add(int camera, CameraFrame frame) {
  const double t = stampS(frame);
  if (newest_s_ >= 0.0 && t < newest_s_ - kJumpBackS) restart();
  newest_s_ = std::max(newest_s_, t);
  Camera& cam = cams_[camera];
  ++cam.stats.frames;
  if (cam.stats.last_stamp_s >= 0.0 && t > cam.stats.last_stamp_s)
    cam.period_s = t - cam.stats.last_stamp_s;
  cam.stats.last_stamp_s = t;
  auto f = std::make_shared<CameraFrame>(std::move(frame));
  cam.frames.push_back(f);
  while (cam.frames.size() > kKeptFrames) {
    cam.frames.pop_front();
    ++cam.stats.dropped;
  }
  if (pending_) {
    if (camera == open_.lead) {
      complete(false);  // a newer lead frame: the pending set waits no longer
    } else {
      completeIfReady();
    }
  }
  // A lead frame after the last set opens the next one (not one at or before it: that set is
  // updated already; the frame waits in its queue and is dropped with the next set).
  const bool still_held = !cam.frames.empty() && cam.frames.back() == f;
  if (!pending_ && still_held && leadFor(t) == camera && (last_set_s_ < 0.0 || t > last_set_s_))
    open(camera);
}

void FrameSets::open(int camera) {
  Camera& cam = cams_[camera];
  open_ = FrameSet();
  open_.lead = camera;
  open_.frames.assign(cams_.size(), nullptr);
  open_.frames[camera] = cam.frames.back();
  open_.header = cam.frames.back()->header;
  cam.frames.pop_back();
  const double t = stampS(*open_.frames[camera]);
  awaited_.assign(cams_.size(), false);
  for (int i = 0; i < cameras(); ++i) {
    // Awaited when its next frame is due within the window: by its period once known (a camera
    // slower than the lead is awaited only for the sets its frames fall in, a camera that
    // stopped only once), else when it was in the last set.
    const double last = cams_[i].stats.last_stamp_s;
    const double period = cams_[i].period_s;
    const bool due = period > 0.0 ? std::abs(last + period - t) <= params_.window_s
                                  : last_set_s_ < 0.0 || last >= last_set_s_ - params_.window_s;
    awaited_[i] = i != camera && params_.wait_s > 0.0 && delivers(i, t) && due;
  }
  pending_ = true;
  ++generation_;
  completeIfReady();
}

void FrameSets::completeIfReady() {
  const double t = open_.header.stamp.toSec();
  for (int i = 0; i < cameras(); ++i) {
    if (!awaited_[i]) continue;
    const Camera& cam = cams_[i];
    if (cam.stats.last_stamp_s > t + params_.window_s) continue;  // it has none for this set
    bool has = false;
    for (const auto& f : cam.frames) has = has || std::abs(stampS(*f) - t) <= params_.window_s;
    if (!has) return;
  }
  complete(false);
}

void FrameSets::expire(unsigned long generation) {
  if (pending_ && generation == generation_) complete(true);
}

void FrameSets::complete(bool waited_in_vain) {
  FrameSet set = std::move(open_);
  pending_ = false;
  set.waited_in_vain = waited_in_vain;
  const double t = set.header.stamp.toSec();
  for (int i = 0; i < cameras(); ++i) {
    Camera& cam = cams_[i];
    // The newest frame within the window; older ones dropped, newer ones kept.
    std::deque<std::shared_ptr<CameraFrame>> kept;
    std::shared_ptr<CameraFrame> in_window;
    for (auto& f : cam.frames) {
      const double s = stampS(*f);
      if (s > t + params_.window_s) {
        kept.push_back(f);
      } else if (i != set.lead && s >= t - params_.window_s) {
        if (in_window) ++cam.stats.dropped;
        in_window = f;
      } else {
        ++cam.stats.dropped;
      }
    }
    cam.frames = std::move(kept);
    if (i != set.lead) set.frames[i] = in_window;
    CameraSetStats& st = cam.stats;
    if (set.frames[i]) {
      ++st.used;
      if (st.dropped_out) transitions_.push_back({i, false, t - st.last_used_s});
      st.dropped_out = false;
      st.last_used_s = t;
    } else if (st.last_stamp_s >= 0.0) {
      ++st.missing;
      const double gap = t - st.last_stamp_s;
      if (gap > params_.timeout_s && !st.dropped_out) {
        st.dropped_out = true;
        transitions_.push_back({i, true, gap});
      }
    }
  }
  last_set_s_ = t;
  ready_.push_back(std::move(set));
}

void FrameSets::restart() {
  for (Camera& cam : cams_) {
    cam.stats.dropped += static_cast<long long>(cam.frames.size());
    cam.frames.clear();
    cam.stats.last_stamp_s = -1.0;  // nobody is waited for before it delivers again
    cam.stats.dropped_out = false;
    cam.stats.last_used_s = -1.0;
    cam.period_s = -1.0;
  }
  if (pending_) ++cams_[open_.lead].stats.dropped;
  pending_ = false;
  open_ = FrameSet();
  last_set_s_ = newest_s_ = -1.0;
}

bool FrameSets::takeReady(FrameSet* out) {
  if (ready_.empty()) return false;
  *out = std::move(ready_.front());
  ready_.pop_front();
  return true;
}

std::vector<CameraTransition> FrameSets::takeTransitions() {
  std::vector<CameraTransition> out;
  out.swap(transitions_);
  return out;
}

}  // namespace gmm_mcl
