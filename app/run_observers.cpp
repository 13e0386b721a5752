#include "app/run_observers.h"

namespace substep::app {

namespace {

// A CSV field: quoted when it holds a comma or a quote (body names may).
std::string csvField(const std::string& s) {
  if (s.find_first_of(",\"") == std::string::npos) return s;
  std::string q = "\"";
  for (char c : s) q += c == '"' ? std::string("\"\"") : std::string(1, c);
  return q + "\"";
}

}  // namespace

TrajectoryCsv::TrajectoryCsv(std::ostream& out, const Model& model, long long every, long long planned)
    : out_(out), model_(model), every_(every), planned_(planned) {
  out_.precision(17);
  out_ << "step,time,body,px,py,pz,qw,qx,qy,qz,vx,vy,vz,wx,wy,wz\n";
}

void TrajectoryCsv::rows(const State& s) {
  for (size_t i = 0; i < model_.bodies.size(); ++i) {
    if (model_.bodies[i].isStatic) continue;
    const BodyState& b = s.bodies[i];
    const Vec3 w = b.worldAngularVelocity();
    out_ << s.step << ',' << s.time << ',' << csvField(model_.bodies[i].name) << ',' << b.x.x() << ',' << b.x.y() << ','
         << b.x.z() << ',' << b.q.w() << ',' << b.q.x() << ',' << b.q.y() << ',' << b.q.z() << ',' << b.v.x() << ','
         << b.v.y() << ',' << b.v.z() << ',' << w.x() << ',' << w.y() << ',' << w.z() << '\n';
  }
}

}  // namespace substep::app
