// Records PCL 1.13's own ROPSEstimation<PointXYZ>::computeEigenVectors, as compiled in Debian's libpcl_features
// 1.13.0+dfsg-3 (this program only calls it), on float32 3x3 matrices.
//
// Input: argv[1], N x 9 float32 (raw, little-endian), each matrix row-major.
// Output: argv[2], N x 9 float32: major, middle and minor axis (one per row).
//
//   g++ -O2 -std=c++17 -I <include dir> -I <eigen3 include dir> -I <pcl-1.13 include dir> \
//       pcl113_rops_axes_probe.cpp -L <lib dir> -Wl,--allow-shlib-undefined \
//       -lpcl_features -lpcl_common -lpcl_search -lpcl_kdtree -lpcl_octree -o pcl113_rops_axes_probe
#include <pcl/point_types.h>
// computeEigenVectors is private: reach the library's compiled function without changing it.
#define private public
#define protected public
#include <pcl/features/rops_estimation.h>
#undef private
#undef protected
#include <cstdio>
#include <vector>

int main(int argc, char** argv) {
  if (argc != 3) return 2;
  std::FILE* f = std::fopen(argv[1], "rb");
  if (!f) return 1;
  std::vector<float> in;
  float buf[9];
  while (std::fread(buf, sizeof(float), 9, f) == 9) in.insert(in.end(), buf, buf + 9);
  std::fclose(f);
  const std::size_t n = in.size() / 9;
  std::vector<float> out(n * 9);
  pcl::ROPSEstimation<pcl::PointXYZ, pcl::Histogram<135>> est;
  for (std::size_t k = 0; k < n; ++k) {
    Eigen::Matrix3f m;
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) m(r, c) = in[k * 9 + r * 3 + c];
    Eigen::Vector3f major, middle, minor;
    est.computeEigenVectors(m, major, middle, minor);
    for (int i = 0; i < 3; ++i) {
      out[k * 9 + i] = major(i);
      out[k * 9 + 3 + i] = middle(i);
      out[k * 9 + 6 + i] = minor(i);
    }
  }
  f = std::fopen(argv[2], "wb");
  if (!f) return 1;
  std::fwrite(out.data(), sizeof(float), out.size(), f);
  std::fclose(f);
  return 0;
}
