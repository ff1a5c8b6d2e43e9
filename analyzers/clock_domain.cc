#include "analyzers/internal/clock_domain.h"

#include "analyzers/internal/channel_timing.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numeric>
#include <tuple>

namespace driftlab::analyzers::internal {
namespace {

/// Streams whose fastest deliveries lie within this of each other at the same arrival time share a clock [us]: a
/// stream late by a second (AMCL's pose) or stamped a second ahead (its transforms) is on its peers' clock; GPS
/// time's 18 s and TAI's 37 s, a time zone or a simulation's offset from the wall clock are clocks of their own.
constexpr double kSameClockUs = 5e6;
/// Windows of arrival time whose fastest deliveries are compared between streams.
constexpr int kProfileBins = 32;
/// A clock more than a day from the log's times counts from another epoch (a simulation's start, a boot): its
/// streams are judged through its mapping [us]. Closer, it is a clock set wrong (GPS time, TAI, a time zone).
constexpr double kAnotherEpochUs = 86400e6;
/// Stamps from before 2001-09-09 are not dates [us].
constexpr double kDateUs = 1e15;
/// A foreign clock's rate is measured over windows of this much arrival time, and only over a log this long [us].
constexpr double kRateWindowUs = 10e6;
/// A clock off the wall clock's rate by more than this is a simulation's: no crystal, nor NTP slewing, is 0.2%
/// off.
constexpr double kSimulationRate = 0.002;

struct Stream {
  const DomainStream* in = nullptr;
  double median_lat = 0;        // arrival - stamp [us]
  double median_stamp = 0;      // [us]
  std::vector<double> profile;  // per window of arrival time: the fastest delivery's arrival - stamp
  std::vector<bool> have;       // whether the window has messages of its own
};

double median_of(std::vector<double> v) {
  if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  if (v.size() % 2 == 1) return *mid;
  return 0.5 * (*mid + *std::max_element(v.begin(), mid));
}

/// arrival - stamp without overflow [us].
double latency_us(int64_t arrival, int64_t stamp) { return static_cast<double>(arrival) - static_cast<double>(stamp); }

int find_root(std::vector<int>& parent, int i) {
  while (parent[static_cast<size_t>(i)] != i)
    i = parent[static_cast<size_t>(i)] = parent[static_cast<size_t>(parent[static_cast<size_t>(i)])];
  return i;
}

/// Whether x is within tolerance of one of the named offsets [s].
bool near(double x, double value, double tolerance = 0.5) { return std::abs(std::abs(x) - value) < tolerance; }

/// The kind and words of a foreign clock from its streams' median arrival - stamp [s] and median stamp [us].
std::pair<std::string, std::string> name_clock(double behind_s, double median_stamp_us, bool arrivals_dates) {
  char buf[256];
  const char* way = behind_s > 0 ? "behind" : "ahead of";
  if (median_stamp_us < kDateUs && arrivals_dates) {
    std::snprintf(buf, sizeof(buf), "stamps count from %.0f s while the log's times are dates", median_stamp_us * 1e-6);
    return {"boot_or_simulation", buf};
  }
  if (near(behind_s, 18) || near(behind_s, 19)) {
    std::snprintf(buf, sizeof(buf), "GPS time: stamps %.3f s %s the log's times (the %.0f s between GPS time and UTC)",
                  std::abs(behind_s), way, std::round(std::abs(behind_s)));
    return {"gps", buf};
  }
  if (near(behind_s, 37)) {
    std::snprintf(buf, sizeof(buf), "TAI: stamps %.3f s %s the log's times (the 37 s between TAI and UTC)",
                  std::abs(behind_s), way);
    return {"tai", buf};
  }
  // GPS seconds count from 1980-01-06, 315,964,800 s after the Unix epoch, and are 18 s ahead of UTC.
  if (near(behind_s, 315964800.0 - 18, 2)) {
    return {"gps_epoch", "GPS time since 1980-01-06 (not the Unix epoch): stamps 315,964,782 s behind the log's times"};
  }
  if (std::abs(behind_s) >= 1800 && std::abs(std::remainder(behind_s, 1800)) < 1) {
    std::snprintf(buf, sizeof(buf), "another time zone: stamps %.1f h %s the log's times", std::abs(behind_s) / 3600,
                  way);
    return {"time_zone", buf};
  }
  std::snprintf(buf, sizeof(buf), "another clock: stamps %.3f s %s the log's times", std::abs(behind_s), way);
  return {"other", buf};
}

}  // namespace

ClockDomains ClockDomains::find(const std::vector<DomainStream>& in, int64_t log_start, int64_t log_end) {
  ClockDomains out;
  const double span = std::max(1.0, static_cast<double>(log_end) - static_cast<double>(log_start));
  auto bin_of = [&](int64_t arrival) {
    const double f = (static_cast<double>(arrival) - static_cast<double>(log_start)) / span;
    return std::clamp(static_cast<int>(f * kProfileBins), 0, kProfileBins - 1);
  };
  std::vector<Stream> streams;
  for (const DomainStream& d : in) {
    const Samples& s = *d.samples;
    if (!s.has_header || s.stamp.size() != s.arrival.size()) continue;
    Stream st;
    st.in = &d;
    st.profile.assign(kProfileBins, std::numeric_limits<double>::infinity());
    st.have.assign(kProfileBins, false);
    std::vector<double> lat, stamps;
    lat.reserve(s.stamp.size());  // grown by doubling, a long stream's copies faulted in its pages twice over
    stamps.reserve(s.stamp.size());
    for (size_t i = 0; i < s.stamp.size(); ++i) {
      if (s.stamp[i] == 0) continue;  // never set: no clock at all
      const double l = latency_us(s.arrival[i], s.stamp[i]);
      lat.push_back(l);
      stamps.push_back(static_cast<double>(s.stamp[i]));
      const int b = bin_of(s.arrival[i]);
      st.profile[static_cast<size_t>(b)] = std::min(st.profile[static_cast<size_t>(b)], l);
      st.have[static_cast<size_t>(b)] = true;
    }
    if (lat.size() * 2 < s.stamp.size() || lat.empty()) continue;  // stamps mostly unset
    st.median_lat = median_of(std::move(lat));
    st.median_stamp = median_of(std::move(stamps));
    // Windows without messages take the nearest window's, so streams that never overlap still compare.
    const size_t bins = st.have.size();
    for (size_t b = 0; b < bins; ++b) {
      if (st.have[b]) continue;
      for (size_t k = 1; k < bins; ++k) {
        if (b >= k && st.have[b - k]) {
          st.profile[b] = st.profile[b - k];
          break;
        }
        if (b + k < bins && st.have[b + k]) {
          st.profile[b] = st.profile[b + k];
          break;
        }
      }
    }
    streams.push_back(std::move(st));
  }
  // Streams on one clock: their fastest deliveries agree where either has messages.
  const int n = static_cast<int>(streams.size());
  std::vector<int> parent(static_cast<size_t>(n));
  std::iota(parent.begin(), parent.end(), 0);
  for (int i = 0; i < n; ++i) {
    for (int j = i + 1; j < n; ++j) {
      const Stream &a = streams[static_cast<size_t>(i)], &b = streams[static_cast<size_t>(j)];
      std::vector<double> diff;
      for (size_t k = 0; k < static_cast<size_t>(kProfileBins); ++k) {
        if (a.have[k] || b.have[k]) diff.push_back(std::abs(a.profile[k] - b.profile[k]));
      }
      if (median_of(std::move(diff)) < kSameClockUs)
        parent[static_cast<size_t>(find_root(parent, i))] = find_root(parent, j);
    }
  }
  std::map<int, std::vector<const Stream*>> groups;
  for (int i = 0; i < n; ++i) groups[find_root(parent, i)].push_back(&streams[static_cast<size_t>(i)]);
  const bool arrivals_dates = static_cast<double>(log_start) >= kDateUs;

  for (const auto& [root, members] : groups) {
    ClockDomain dom;
    std::vector<double> lats, stamps;
    for (const Stream* m : members) {
      dom.channels.push_back(m->in->name);
      lats.push_back(m->median_lat);
      stamps.push_back(m->median_stamp);
    }
    const double behind_us = median_of(lats);
    dom.offset_s = behind_us * 1e-6;
    const bool recorder = std::abs(behind_us) < kSameClockUs;
    dom.mapped = std::abs(behind_us) > kAnotherEpochUs;
    Mapping mapping;
    mapping.identity = !dom.mapped;
    if (recorder) {
      dom.kind = "recorder";
      dom.description = "the recorder's clock (the log's times)";
    } else {
      std::tie(dom.kind, dom.description) = name_clock(dom.offset_s, median_of(stamps), arrivals_dates);
    }
    // The reference: per window of stamps, the fastest delivery. A simulator's clock (/clock) recorded with the
    // streams is theirs alone: it is sent as the simulation's time ticks, so the others' latency is against the
    // simulation itself, and a bridge delaying every sensor shows. Without it, transforms are left out when other
    // streams are there: a transform may be post-dated on purpose (AMCL's transform_tolerance), which would make
    // every other stream look late.
    std::vector<const Stream*> refs;
    for (const Stream* m : members) {
      if (m->in->is_clock) refs.push_back(m);
    }
    if (!refs.empty()) dom.reference = refs.front()->in->name;
    for (const Stream* m : members) {
      if (dom.reference.empty() && !m->in->is_tf) refs.push_back(m);
    }
    if (refs.empty()) refs = members;
    double s_lo = std::numeric_limits<double>::infinity(), s_hi = -s_lo;
    for (const Stream* m : refs) {
      for (const int64_t t : m->in->samples->stamp) {
        if (t == 0) continue;
        s_lo = std::min(s_lo, static_cast<double>(t));
        s_hi = std::max(s_hi, static_cast<double>(t));
      }
    }
    // Windows of a second of stamps (400 at most): long enough for the streams to deliver, short enough to follow
    // a real-time factor as it changes.
    const double width = std::max(1e6, (s_hi - s_lo) / 400);
    const size_t bins = static_cast<size_t>(std::max(0.0, std::floor((s_hi - s_lo) / width))) + 1;
    struct Fastest {
      double lat = std::numeric_limits<double>::infinity();
      double stamp = 0;
    };
    std::vector<std::vector<Fastest>> per_stream(members.size(), std::vector<Fastest>(bins));
    for (size_t k = 0; k < members.size(); ++k) {
      const Samples& s = *members[k]->in->samples;
      for (size_t i = 0; i < s.stamp.size(); ++i) {
        const auto t = static_cast<double>(s.stamp[i]);
        if (s.stamp[i] == 0 || t < s_lo || t > s_hi) continue;
        const auto b = std::min(bins - 1, static_cast<size_t>((t - s_lo) / width));
        const double l = latency_us(s.arrival[i], s.stamp[i]);
        if (l < per_stream[k][b].lat) per_stream[k][b] = {l, t};
      }
    }
    std::vector<std::pair<double, double>> knots;
    for (size_t b = 0; b < bins; ++b) {
      std::vector<Fastest> here;
      for (size_t k = 0; k < members.size(); ++k) {
        if (std::find(refs.begin(), refs.end(), members[k]) == refs.end()) continue;
        if (std::isfinite(per_stream[k][b].lat)) here.push_back(per_stream[k][b]);
      }
      if (here.empty()) continue;
      const Fastest& f =
          *std::min_element(here.begin(), here.end(), [](const Fastest& x, const Fastest& y) { return x.lat < y.lat; });
      knots.emplace_back(f.stamp, f.lat);
    }
    // A window's fastest delivery can be a message stamped long before it was sent (AMCL's initial pose) or after
    // the fact: a knot more than 50 ms off the line through the five around it (Theil-Sen: the median of their
    // pairwise slopes, then of their intercepts) is left out. The line follows a real-time factor's slope, even
    // a slow simulation's; delivery jitter stays well inside.
    if (knots.size() >= 3) {
      std::vector<std::pair<double, double>> kept;
      for (size_t i = 0; i < knots.size(); ++i) {
        const size_t width = std::min<size_t>(knots.size(), 5);
        const size_t lo = std::min(i < 2 ? 0 : i - 2, knots.size() - width);
        std::vector<double> slopes, intercepts;
        for (size_t a = lo; a < lo + width; ++a) {
          for (size_t b = a + 1; b < lo + width; ++b) {
            const double ds = knots[b].first - knots[a].first;
            if (ds > 0) slopes.push_back((knots[b].second - knots[a].second) / ds);
          }
        }
        const double slope = slopes.empty() ? 0 : median_of(std::move(slopes));
        for (size_t k = lo; k < lo + width; ++k) {
          intercepts.push_back(knots[k].second - slope * (knots[k].first - knots[i].first));
        }
        if (std::abs(knots[i].second - median_of(std::move(intercepts))) <= 50e3) kept.push_back(knots[i]);
      }
      knots = std::move(kept);
    }
    for (const auto& [stamp, lat] : knots) mapping.knots.push_back({stamp, lat});
    // The clock's rate: stamps against arrivals along the reference, over the log and over 10 s windows.
    if (!recorder && knots.size() >= 2) {
      auto arrival = [](const std::pair<double, double>& k) { return k.first + k.second; };
      const double a_span = arrival(knots.back()) - arrival(knots.front());
      if (a_span >= kRateWindowUs) {
        dom.rate_valid = true;
        dom.rate = (knots.back().first - knots.front().first) / a_span;
        dom.rate_min = dom.rate_max = dom.rate;
        size_t from = 0;
        for (size_t i = 1; i < knots.size(); ++i) {
          const double da = arrival(knots[i]) - arrival(knots[from]);
          if (da < kRateWindowUs) continue;
          const double r = (knots[i].first - knots[from].first) / da;
          dom.rate_min = std::min(dom.rate_min, r);
          dom.rate_max = std::max(dom.rate_max, r);
          from = i;
        }
      }
      char buf[256];
      if (dom.kind == "boot_or_simulation") {
        if (dom.rate_valid && std::abs(dom.rate - 1) > kSimulationRate) {
          dom.kind = "simulation";
          std::snprintf(buf, sizeof(buf),
                        "simulation time (use_sim_time): %s, running at %.2f%% of real time (%.2f%% to %.2f%% over "
                        "10 s)",
                        dom.description.c_str(), dom.rate * 100, dom.rate_min * 100, dom.rate_max * 100);
        } else {
          std::snprintf(buf, sizeof(buf), "time since boot, or simulation time at real time: %s",
                        dom.description.c_str());
        }
        dom.description = buf;
      }
    }
    // Each stream against the reference: its fastest delivery per window above the reference's there.
    for (size_t k = 0; k < members.size(); ++k) {
      std::vector<double> delays;
      for (size_t b = 0; b < bins; ++b) {
        const Fastest& f = per_stream[k][b];
        if (std::isfinite(f.lat) && !knots.empty()) delays.push_back(f.lat - mapping.at(f.stamp));
      }
      const double delay = members.size() >= 2 || !dom.reference.empty() ? median_of(std::move(delays)) * 1e-6
                                                                         : std::numeric_limits<double>::quiet_NaN();
      out.peer_delay_s_[members[k]->in->name] = delay;
      out.channel_domain_[members[k]->in->name] = static_cast<int>(out.domains_.size());
    }
    if (!mapping.identity) {
      for (const auto& [stamp, lat] : mapping.knots) dom.mapping.push_back({stamp * 1e-6, lat * 1e-6});
    }
    out.domains_.push_back(std::move(dom));
    out.mappings_.push_back(std::move(mapping));
  }
  return out;
}

int ClockDomains::domain_of(const std::string& channel) const {
  const auto it = channel_domain_.find(channel);
  return it == channel_domain_.end() ? -1 : it->second;
}

int64_t ClockDomains::to_arrival(int d, int64_t stamp) const {
  if (d < 0 || mappings_[static_cast<size_t>(d)].identity || stamp == 0) return stamp;
  const double t = static_cast<double>(stamp) + mappings_[static_cast<size_t>(d)].at(static_cast<double>(stamp));
  constexpr double kLast = 9223372036854774784.0;  // the largest double below 2^63
  return static_cast<int64_t>(std::llround(std::clamp(t, -kLast, kLast)));
}

double ClockDomains::peer_delay_s(const std::string& channel) const {
  const auto it = peer_delay_s_.find(channel);
  return it == peer_delay_s_.end() ? std::numeric_limits<double>::quiet_NaN() : it->second;
}

bool is_clock_source(const std::string& source_type) {
  return source_type == "rosgraph_msgs/Clock" || source_type == "rosgraph_msgs/msg/Clock";
}

void judge_domains(Diagnosis& d) {
  char buf[768];
  // The clock most streams are on (the recorder's among equals) is the recording's; others are a wrong time base.
  // A simulator's clock channel is simulation time by definition, whichever clock the others use: never counted,
  // never a wrong time base.
  std::vector<size_t> members(d.domains.size(), 0);
  for (const auto& c : d.channels) {
    if (c.domain >= 0 && !is_clock_source(c.source_type)) ++members[static_cast<size_t>(c.domain)];
  }
  int main_domain = -1;
  for (size_t i = 0; i < d.domains.size(); ++i) {
    const auto best = main_domain < 0 ? 0 : members[static_cast<size_t>(main_domain)];
    if (main_domain < 0 || members[i] > best || (members[i] == best && d.domains[i].kind == "recorder")) {
      main_domain = static_cast<int>(i);
    }
  }
  auto is_set_wrong = [](const ClockDomain& x) {
    return x.kind == "gps" || x.kind == "gps_epoch" || x.kind == "tai" || x.kind == "time_zone" || x.kind == "other";
  };
  for (auto& c : d.channels) {
    if (c.domain < 0 || is_clock_source(c.source_type)) continue;
    const ClockDomain& own = d.domains[static_cast<size_t>(c.domain)];
    if (c.domain != main_domain) {
      const ClockDomain& main = d.domains[static_cast<size_t>(main_domain)];
      const double off = own.offset_s - main.offset_s;
      std::string hint;
      if (own.kind == "recorder" && (main.kind == "simulation" || main.kind == "boot_or_simulation")) {
        hint = ": its node stamps with the wall clock (use_sim_time not set on it?)";
      } else if ((own.kind == "simulation" || own.kind == "boot_or_simulation") && main.kind == "recorder") {
        hint = ": its node stamps with simulation time or time since boot (use_sim_time set on it alone?)";
      }
      std::snprintf(buf, sizeof(buf),
                    "stamped on another clock than its %zu peer%s (%s; theirs: %s), %.3f s apart%s: data combined "
                    "across the two is matched wrongly or dropped as stale",
                    members[static_cast<size_t>(main_domain)],
                    members[static_cast<size_t>(main_domain)] == 1 ? "" : "s", own.description.c_str(),
                    main.description.c_str(), std::abs(off), hint.c_str());
      add_reason(c, true, buf, Cause::kClock);
    } else if (is_set_wrong(own)) {
      add_reason(c, true, "stamped on " + own.description, Cause::kClock);
    }
    // Latency on a clock of another epoch is against /clock where it was recorded, else against the stream's
    // peers: a stream arriving 10 ms (a 100 Hz period, more than a scheduler's delay) after it is late.
    constexpr double kLatePeer_s = 0.010;
    if (own.mapped && std::isfinite(c.peer_delay_s) && c.peer_delay_s >= kLatePeer_s && c.type != "driftlab.tf_t") {
      const std::string clock = own.kind == "simulation" ? "simulation time" : own.description;
      if (own.reference.empty()) {
        std::snprintf(buf, sizeof(buf),
                      "arrives %.1f ms after the fastest streams on its clock (%s), by its fastest deliveries "
                      "against theirs: late, or stamped early",
                      c.peer_delay_s * 1e3, clock.c_str());
      } else {
        std::snprintf(buf, sizeof(buf),
                      "arrives %.1f ms after the simulator's clock (%s, %s) reached its stamps, by its fastest "
                      "deliveries: late, or stamped early",
                      c.peer_delay_s * 1e3, own.reference.c_str(), clock.c_str());
      }
      add_reason(c, false, buf, Cause::kLate);
    }
  }
  // Transforms received older than one before them, per transform (the channel's messages interleave several
  // broadcasters: odometry's, AMCL's, the robot state publisher's, which is no reordering).
  for (const TfEdge& e : d.tf.edges) {
    if (e.out_of_order == 0) continue;
    for (auto& c : d.channels) {
      if (c.name != e.channel) continue;
      c.out_of_order_stamp += e.out_of_order;
      std::snprintf(buf, sizeof(buf),
                    "%lld transforms '%s' -> '%s' arrived after a newer one of the same transform "
                    "(reordered)",
                    static_cast<long long>(e.out_of_order), e.parent.c_str(), e.child.c_str());
      add_reason(c, true, buf, Cause::kSymptom);
    }
  }
}

void judge_late_streams(Diagnosis& d) {
  // The typical stream of each clock judged as stamped: the median of its streams' delays against the fastest.
  // The fastest may be a stream stamped ahead (a clock running ahead, its own fault), so the typical one is the
  // reference; transforms (post-dated on purpose) and the simulator's clock are left out.
  std::vector<std::vector<double>> delays(d.domains.size());
  auto judged = [&](const ChannelTiming& c) {
    return c.domain >= 0 && !d.domains[static_cast<size_t>(c.domain)].mapped && std::isfinite(c.peer_delay_s) &&
           c.type != "driftlab.tf_t" && !is_clock_source(c.source_type);
  };
  for (const auto& c : d.channels) {
    if (judged(c)) delays[static_cast<size_t>(c.domain)].push_back(c.peer_delay_s);
  }
  char buf[512];
  for (auto& c : d.channels) {
    const auto& peers = judged(c) ? delays[static_cast<size_t>(c.domain)] : std::vector<double>{};
    if (peers.size() < 3) continue;  // a median of two is either
    // Already late by a finding that says more (the command loop's delay, which the transport is part of).
    if (std::find(c.causes.begin(), c.causes.end(), Cause::kLate) != c.causes.end()) continue;
    const double late_s = c.peer_delay_s - median_of(peers);
    // 10 ms, as on a foreign clock; the sensors stamped when their acquisition starts and sent when it ends (a
    // camera's exposure, a lidar's sweep) may take a period of theirs more, which is how they work.
    const bool acquires =
        c.type == "driftlab.image_t" || c.type == "driftlab.point_cloud_t" || c.type == "driftlab.laser_scan_t";
    constexpr double kLatePeer_s = 0.010;
    if (late_s < kLatePeer_s + (acquires ? c.expected_period_s : 0)) continue;
    const ClockDomain& own = d.domains[static_cast<size_t>(c.domain)];
    std::snprintf(buf, sizeof(buf),
                  "arrives %.1f ms after the typical stream on its clock (%s), by its fastest deliveries against "
                  "theirs: late, or stamped early",
                  late_s * 1e3, own.kind == "recorder" ? "the recorder's" : own.description.c_str());
    add_reason(c, false, buf, Cause::kLate);
  }
}

}  // namespace driftlab::analyzers::internal

namespace driftlab::analyzers {

double mapped_offset_s(const std::vector<std::array<double, 2>>& knots, double stamp) {
  if (knots.empty()) return 0;
  if (knots.size() == 1) return knots.front()[1];
  auto it = std::lower_bound(knots.begin(), knots.end(), stamp,
                             [](const std::array<double, 2>& k, double s) { return k[0] < s; });
  if (it == knots.begin()) ++it;
  if (it == knots.end()) --it;
  const auto& [s1, l1] = *it;
  const auto& [s0, l0] = *(it - 1);
  if (s1 <= s0) return l1;
  return l0 + (l1 - l0) * (stamp - s0) / (s1 - s0);
}

}  // namespace driftlab::analyzers
