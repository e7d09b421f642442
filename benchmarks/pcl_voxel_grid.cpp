// Times PCL's pcl::VoxelGrid (the filter Loureiro et al. 2021 used) on one cloud, so that
// benchmarks/bench_detectors.py can compare our voxel grid with the paper's own implementation
// on the same machine and the same points. Built and run by that script when PCL's headers
// are installed (Debian: libpcl-dev); not part of the product.
//
// usage: pcl_voxel_grid CLOUD.f64 REPEATS LEAF [LEAF ...]
//   CLOUD.f64: N x 3 little-endian float64 (x, y, z) rows, metres.
// prints one line per leaf size: "<leaf> <points out> <least ms of REPEATS runs>", or
// "<leaf> refused" where PCL declines the leaf size (its int32 voxel indices would overflow;
// it then returns the input unfiltered, which would time a copy).

#include <pcl/common/common.h>
#include <pcl/filters/voxel_grid.h>
#include <pcl/point_types.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <vector>

int main(int argc, char** argv) {
  if (argc < 4) {
    std::fprintf(stderr, "usage: %s CLOUD.f64 REPEATS LEAF [LEAF ...]\n", argv[0]);
    return 2;
  }
  std::ifstream in(argv[1], std::ios::binary);
  in.seekg(0, std::ios::end);
  const std::size_t bytes = static_cast<std::size_t>(in.tellg());
  in.seekg(0);
  std::vector<double> xyz(bytes / sizeof(double));
  in.read(reinterpret_cast<char*>(xyz.data()), static_cast<std::streamsize>(bytes));
  const std::size_t n = xyz.size() / 3;

  pcl::PointCloud<pcl::PointXYZ>::Ptr cloud(new pcl::PointCloud<pcl::PointXYZ>);
  cloud->resize(n);
  for (std::size_t i = 0; i < n; ++i)
    (*cloud)[i] = pcl::PointXYZ(static_cast<float>(xyz[3 * i]), static_cast<float>(xyz[3 * i + 1]),
                                static_cast<float>(xyz[3 * i + 2]));
  Eigen::Vector4f lo, hi;
  pcl::getMinMax3D(*cloud, lo, hi);

  const int repeats = std::atoi(argv[2]);
  for (int a = 3; a < argc; ++a) {
    const float leaf = static_cast<float>(std::atof(argv[a]));
    // PCL's own overflow test (VoxelGrid::applyFilter), checked here to report it plainly.
    const double voxels = (static_cast<std::int64_t>((hi[0] - lo[0]) / leaf) + 1.0) *
                          (static_cast<std::int64_t>((hi[1] - lo[1]) / leaf) + 1.0) *
                          (static_cast<std::int64_t>((hi[2] - lo[2]) / leaf) + 1.0);
    if (voxels > static_cast<double>(std::numeric_limits<std::int32_t>::max())) {
      std::printf("%g refused\n", leaf);
      continue;
    }
    double best = std::numeric_limits<double>::infinity();
    std::size_t out_points = 0;
    for (int r = 0; r < repeats; ++r) {
      pcl::PointCloud<pcl::PointXYZ> out;
      const auto t0 = std::chrono::steady_clock::now();
      pcl::VoxelGrid<pcl::PointXYZ> grid;
      grid.setInputCloud(cloud);
      grid.setLeafSize(leaf, leaf, leaf);
      grid.filter(out);
      const double ms =
          std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
      best = std::min(best, ms);
      out_points = out.size();
    }
    std::printf("%g %zu %.4f\n", leaf, out_points, best);
  }
  return 0;
}
