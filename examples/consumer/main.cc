// Composes two similarity transforms through the installed library and checks the round trip.
#include <cstdio>

#include <sparseloop/core/sim3.h>

int main() {
  sparseloop::Vector7d tangent;
  tangent << 0.1, -0.2, 0.3, 0.01, 0.02, -0.03, 0.1;
  const sparseloop::Sim3d a = sparseloop::Sim3d::Exp(tangent);
  const sparseloop::Sim3d identity = a * a.Inverse();
  const double err = identity.Log().norm();
  std::printf("sparseloop consumer: |log(a * a^-1)| = %.3g\n", err);
  return err < 1e-9 ? 0 : 1;
}
