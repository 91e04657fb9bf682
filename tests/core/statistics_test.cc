#include "sparseloop/core/statistics.h"

#include <cmath>
#include <random>
#include <stdexcept>

#include <gtest/gtest.h>

namespace sparseloop {
namespace {

// Values NumPy prints for numpy.percentile(v, 100 * q) (method "linear").
TEST(Statistics, PercentileMatchesNumpyLinear) {
  const std::vector<double> v = {7, 1, 3, 10};  // sorted: 1 3 7 10
  EXPECT_DOUBLE_EQ(Percentile(v, 0.0), 1.0);
  EXPECT_DOUBLE_EQ(Percentile(v, 0.5), 5.0);   // mean of the two middle values
  EXPECT_DOUBLE_EQ(Percentile(v, 0.9), 9.1);   // 7 + 0.7 * 3
  EXPECT_DOUBLE_EQ(Percentile(v, 0.25), 2.5);  // 1 + 0.75 * 2
  EXPECT_DOUBLE_EQ(Percentile(v, 1.0), 10.0);
  EXPECT_DOUBLE_EQ(Percentile({4, 2, 9}, 0.5), 4.0);
  EXPECT_DOUBLE_EQ(Percentile({3.5}, 0.99), 3.5);
  EXPECT_EQ(Percentile({}, 0.5), 0.0);
  EXPECT_THROW(Percentile(v, 1.5), std::invalid_argument);
  EXPECT_THROW(Percentile(v, -0.1), std::invalid_argument);
  EXPECT_THROW(Percentile(v, std::nan("")), std::invalid_argument);
}

// Monotone in q and bounded by the values, on random samples of many sizes.
TEST(Statistics, PercentileIsMonotoneAndWithinTheValues) {
  std::mt19937_64 rng(3);
  std::exponential_distribution<double> d(1.0);
  for (size_t n = 1; n < 40; ++n) {
    std::vector<double> v(n);
    for (double& x : v) x = d(rng);
    const auto [lo, hi] = std::minmax_element(v.begin(), v.end());
    double last = *lo;
    for (double q = 0.0; q <= 1.0; q += 0.01) {
      const double p = Percentile(v, q);
      EXPECT_GE(p, last - 1e-12);
      EXPECT_LE(p, *hi);
      last = p;
    }
  }
}

}  // namespace
}  // namespace sparseloop

namespace sparseloop {
namespace {

// Against tabulated chi-square quantiles (e.g. NIST/SEMATECH): within 1.5 % for dof >= 3 over
// the quantiles the NEES and PCM checks use, 3 % in the lower tail (Wilson-Hilferty: 1.268
// against 1.237 at p = 0.025, dof 6); bad arguments throw.
TEST(ChiSquareQuantile, MatchesTablesAndRefusesBadArguments) {
  struct Row {
    double p;
    int dof;
    double value;
  };
  for (const Row& r : {Row{0.95, 6, 12.592}, Row{0.975, 6, 14.449}, Row{0.025, 6, 1.237},
                       Row{0.95, 7, 14.067}, Row{0.99, 3, 11.345}, Row{0.5, 7, 6.346},
                       Row{0.9973, 6, 20.062}, Row{0.025, 700, 628.0}, Row{0.975, 700, 775.8}}) {
    SCOPED_TRACE(testing::Message() << r.p << " " << r.dof);
    EXPECT_NEAR(ChiSquareQuantile(r.p, r.dof), r.value, (r.p < 0.05 ? 0.03 : 0.015) * r.value);
  }
  EXPECT_THROW(ChiSquareQuantile(0.0, 3), std::invalid_argument);
  EXPECT_THROW(ChiSquareQuantile(1.0, 3), std::invalid_argument);
  EXPECT_THROW(ChiSquareQuantile(0.5, 0), std::invalid_argument);
  EXPECT_THROW(ChiSquareQuantile(std::nan(""), 3), std::invalid_argument);
}

}  // namespace
}  // namespace sparseloop
