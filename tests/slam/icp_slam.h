// MRPT's icp-slam application (Debian's mrpt-apps), the 2D SLAM module's peer, run from tests.
#pragma once

#include <fstream>
#include <sstream>
#include <string>

#include "tests/test_util.h"

namespace driftlab::test {

inline const std::string kIcpSlamIni = "/usr/share/mrpt/config_files/icp-slam/icp-slam_demo_classic.ini";

/// Runs icp-slam on a rawlog in `dir` with its demo configuration (windows and scene dumps off), its output in
/// dir/icp (log_estimated_path.txt: step x y yaw); its exit code.
inline int run_icp_slam(const TempDir& dir, const std::string& rawlog) {
  std::ifstream in(kIcpSlamIni);
  std::stringstream ini;
  for (std::string line; std::getline(in, line);) {
    if (line.rfind("SHOW_PROGRESS_3D_REAL_TIME=", 0) == 0) line = "SHOW_PROGRESS_3D_REAL_TIME=0";
    if (line.rfind("SAVE_3D_SCENE=", 0) == 0) line = "SAVE_3D_SCENE=0";
    if (line.rfind("LOG_FREQUENCY=", 0) == 0) line = "LOG_FREQUENCY=0";
    if (line.rfind("logOutput_dir=", 0) == 0) line = "logOutput_dir=" + dir.file("icp");
    ini << line << "\n";
  }
  std::ofstream(dir.file("icp.ini")) << ini.str();
  return run("cd " + dir.path() + " && icp-slam icp.ini '" + rawlog + "' >icp.out 2>&1");
}

}  // namespace driftlab::test
