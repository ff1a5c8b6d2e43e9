// A scanner's "no return" code found in its readings. A SICK reports a fixed value near its maximum range for every
// beam without an echo. When range_max carries that value, mrpt_scan.h drops the readings there; a log converted by
// another tool may carry a larger range_max (the bags made from MIT Killian's CARMEN log say 80 m while the scanner
// answers 51.05-51.12 m for no echo, 1.3% of its readings), and those readings become points that sit at the same
// place ahead of the robot however it moves: in a corridor, the only thing pinning the position along it, and the
// front end drags. Such a code shows as a pile at the very top of the readings: many readings within 1% of the
// largest, few just below them and none beyond. Echoes do not pile up there: the farthest walls give a thin tail.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <optional>
#include <utility>
#include <vector>

namespace driftlab::slam::internal {

class NoReturnCode {
 public:
  /// Counts the readings a scan gives as echoes (finite, at least range_min, below 99% of range_max), until a code
  /// is found; then nothing changes.
  void observe(const std::vector<float>& ranges, float range_min, float range_max) {
    if (from_) return;
    bool added = false;
    for (size_t i = 0; i < ranges.size(); ++i) {
      const float r = ranges[i];
      if (!(r >= range_min && r < 0.99f * range_max && r >= kLowest && r < kHighest)) continue;
      // The test looks at most 14% below the largest reading (the pile within its top 3%, and 10% under the pile):
      // readings a fifth or more below the largest so far never count.
      if (r < 0.8f * top_) continue;
      top_ = std::max(top_, r);
      const auto b = static_cast<size_t>(std::log(r / kLowest) / kBinLog);
      if (b >= bins_.size()) bins_.resize(b + 1);
      Bin& bin = bins_[b];
      ++bin.count, added = true;
      const auto beam = static_cast<uint32_t>(i);
      if (bin.beams.size() < kMinBeams && std::find(bin.beams.begin(), bin.beams.end(), beam) == bin.beams.end()) {
        bin.beams.push_back(beam);
      }
      const auto mm = static_cast<int64_t>(std::lround(static_cast<double>(r) * 1000));
      auto v = std::find_if(bin.values.begin(), bin.values.end(), [&](const auto& p) { return p.first == mm; });
      if (v != bin.values.end()) {
        ++v->second;
      } else if (bin.values.size() < kValues) {
        bin.values.emplace_back(mm, 1);
      }
    }
    if (added) decide();
  }
  /// Readings at or beyond this are the code, once found.
  std::optional<float> from() const { return from_; }
  /// The readings in the pile when it was found.
  int64_t pile() const { return pile_; }

  static constexpr int64_t kMinPile = 100;   ///< readings a pile needs (a few scans' worth of no-echo beams)
  static constexpr int kRatio = 10;          ///< ... and this many times those in the 9% just below it, ...
  static constexpr size_t kMinBeams = 20;    ///< ... from this many beams (not a doorway a standing robot sees) ...
  static constexpr double kModeShare = 0.5;  ///< ... and this share of them at one value, to the millimetre (a far
                                             ///< wall's readings spread across the 1%, a code's do not)

 private:
  static constexpr float kLowest = 1, kHighest = 1e5;  // [m]; nearer readings are never a scanner's maximum
  static constexpr double kBinLog = 0.005;             // each bin 0.5% of its range wide
  static constexpr size_t kValues = 64;                // distinct values a bin keeps counts of
  struct Bin {
    int64_t count = 0;
    std::vector<uint32_t> beams;                      // the first kMinBeams distinct beams
    std::vector<std::pair<int64_t, int64_t>> values;  // the first kValues distinct values [mm] and their counts
  };

  void decide() {
    // The pile: the two adjacent bins (1%) with the most readings among the top six, with nothing beyond it but
    // stray readings (at most 1% of it).
    size_t top = bins_.size();
    while (top > 0 && bins_[top - 1].count == 0) --top;
    if (top < 2) return;
    size_t best = top - 1;
    int64_t pile = -1;
    for (size_t b = top - 1; b >= 1 && b + 6 > top; --b) {
      if (const int64_t c = bins_[b].count + bins_[b - 1].count; c > pile) best = b, pile = c;
    }
    int64_t above = 0, below = 0;
    for (size_t b = best + 1; b < top; ++b) above += bins_[b].count;
    for (size_t b = best >= 20 ? best - 20 : 0; b + 1 < best; ++b) below += bins_[b].count;
    if (pile < kMinPile || pile < kRatio * below || above * 100 > pile) return;
    std::vector<uint32_t> beams = bins_[best].beams;
    for (uint32_t beam : bins_[best - 1].beams) {
      if (std::find(beams.begin(), beams.end(), beam) == beams.end()) beams.push_back(beam);
    }
    int64_t mode = 0;
    for (const Bin* bin : {&bins_[best], &bins_[best - 1]}) {
      for (const auto& [mm, count] : bin->values) mode = std::max(mode, count);
    }
    if (beams.size() < kMinBeams || static_cast<double>(mode) < kModeShare * static_cast<double>(pile)) return;
    from_ = kLowest * static_cast<float>(std::exp(kBinLog * static_cast<double>(best - 1)));
    pile_ = pile;
    bins_.clear();
  }

  std::vector<Bin> bins_;
  float top_ = 0;  // the largest reading counted
  std::optional<float> from_;
  int64_t pile_ = 0;
};

}  // namespace driftlab::slam::internal
