// The icp-slam method's library (slam/internal/icp_slam.h): MRPT's ICP map builder, loaded only when chosen.
#include <mrpt/slam/CMetricMapBuilderICP.h>
#include <mrpt/system/COutputLogger.h>

#include "slam/internal/icp_slam.h"
#include "slam/internal/point_maps.h"

namespace driftlab::slam::internal {
namespace {

class MrptIcpSlam final : public IcpSlamBuilder {
 public:
  explicit MrptIcpSlam(const mrpt::config::CConfigFileBase& ini) {
    builder_.setMinLoggingLevel(mrpt::system::LVL_ERROR);
    builder_.ICP_options.loadFromConfigFile(ini, "MappingApplication");
    builder_.ICP_params.loadFromConfigFile(ini, "ICP");
    builder_.initialize();
  }

  size_t process(mrpt::obs::CActionCollection& actions, mrpt::obs::CSensoryFrame& frame) override {
    builder_.processActionObservation(actions, frame);
    const size_t size = builder_.getCurrentlyBuiltMapSize();
    // A new keyframe means the scan went into the points map; with fuse_points the map's kd-tree is left stale
    // by MRPT (see mark_point_maps_modified), so the next scans would match against the map as it was before.
    if (size != size_) mark_point_maps_modified(*builder_.getCurrentlyBuiltMetricMap());
    size_ = size;
    return size;
  }

  void estimate(mrpt::math::CMatrixDouble66& covariance, mrpt::poses::CPose3D& mean) const override {
    builder_.getCurrentPoseEstimation()->getCovarianceAndMean(covariance, mean);
  }

  void keyframes(mrpt::maps::CSimpleMap& out) const override { builder_.getCurrentlyBuiltMap(out); }

 private:
  mrpt::slam::CMetricMapBuilderICP builder_;
  size_t size_ = 0;
};

}  // namespace
}  // namespace driftlab::slam::internal

extern "C" __attribute__((visibility("default"))) driftlab::slam::internal::IcpSlamBuilder* driftlab_make_icp_slam(
    const mrpt::config::CConfigFileBase* ini) {
  return new driftlab::slam::internal::MrptIcpSlam(*ini);
}
