// Where a measurement comes from: the source commit, the machine, the time. The lab's records
// and substep-bench's JSON carry these, so that figures from different trees are not compared
// by mistake.
#pragma once

#include <string>

namespace substep::lab {

// The commit of the source tree the program was built from, as git sees it now ("abc1234");
// without git or the source tree (an installed substep), the commit it was built from; "unknown"
// when neither is known.
std::string sourceCommit();
// The commit and how many files under physics/ differ from it (the timings and trajectories
// depend on them): "abc1234 + uncommitted changes in 2 file(s) under physics/"; as built when
// git cannot tell now.
std::string sourceState();
std::string cpuModel();     // /proc/cpuinfo's model name, "unknown CPU" elsewhere
std::string loadAverage();  // /proc/loadavg's 1, 5 and 15 minute averages, "unknown" elsewhere
std::string utcNow();       // "2026-12-01T20:04:05Z"

}  // namespace substep::lab
