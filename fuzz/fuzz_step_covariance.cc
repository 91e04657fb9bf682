// Fuzzes the odometry-covariance reader (`run --odometry-covariance`: key + 21 or 36 numbers).
// An accepted file holds finite, symmetric, positive definite matrices with increasing keys.
#include <cmath>
#include <cstdlib>

#include <Eigen/Cholesky>

#include "fuzz_util.h"
#include "sparseloop/core/error.h"
#include "sparseloop/io/step_covariance.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto path = sparseloop::fuzz::WriteInput(data, size, "covariance.txt");
  try {
    const auto rows = sparseloop::ReadStepCovariances(path);
    for (size_t i = 0; i < rows.size(); ++i) {
      const auto& c = rows[i].covariance;
      if (!c.allFinite() || !std::isfinite(rows[i].key)) std::abort();
      if (i > 0 && !(rows[i].key > rows[i - 1].key)) std::abort();
      if ((c - c.transpose()).cwiseAbs().maxCoeff() > 1e-9 * c.cwiseAbs().maxCoeff()) std::abort();
      if (Eigen::LLT<Eigen::Matrix<double, 6, 6>>(c).info() != Eigen::Success) std::abort();
    }
  } catch (const sparseloop::Error&) {
  }
  return 0;
}
