# The Debian package of everything installed (scripts/package): driftlab_VERSION_ARCH.deb, for /usr.
# Depends: the shared libraries' packages as dpkg-shlibdeps finds them from the programs (Bullet, MRPT, PCL,
# OpenCV, LCM, urdfdom, yaml-cpp, ...), and what the programs run rather than link: python3 with matplotlib and
# NumPy, for `driftlab report`, `demo` and the sweep's page.
set(CPACK_GENERATOR DEB)
set(CPACK_PACKAGE_NAME driftlab)
set(CPACK_PACKAGE_VERSION ${DRIFTLAB_VERSION})
set(CPACK_PACKAGE_DESCRIPTION_SUMMARY "record, replay and diagnose robot logs")
set(CPACK_PACKAGE_DESCRIPTION
  "driftlab records, simulates and replays robot logs (LCM event logs, ROS bags, MCAP, PX4 ULog, CARMEN) on a\n\
virtual clock, and diagnoses their timing: skew, clock offsets and drift, latency, drops and reordering.")
set(CPACK_PACKAGE_CONTACT "driftlab maintainers <maintainers@users.noreply.h-seed-73599b4b.example>")
set(CPACK_PACKAGING_INSTALL_PREFIX /usr)
set(CPACK_STRIP_FILES ON)
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)
set(CPACK_DEBIAN_PACKAGE_SECTION science)
set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS ON)
set(CPACK_DEBIAN_PACKAGE_DEPENDS "python3, python3-matplotlib, python3-numpy, libjs-dygraphs")
set(CPACK_DEBIAN_PACKAGE_SUGGESTS "bash-completion")
include(CPack)
