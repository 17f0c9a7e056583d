// Records Eigen 3.4's EigenSolver<Matrix3f> (the solver of PCL's RoPS LRF) on float32 3x3 matrices.
//
// Input: argv[1], N x 9 float32 (raw, little-endian), each matrix row-major.
// Output: argv[2], N x 25 float32: status (1 = Success), eigenvalues re[3], im[3], eigenvectors re[3x3],
// im[3x3] (row-major; column j is eigenvector j, as eigenvectors() returns it).
//
// Built like Debian's libpcl 1.13 (x86-64 baseline = SSE2, no FMA, -O2, no -march, no -ffast-math), against
// Eigen 3.4.0's headers (Debian libeigen3-dev 3.4.0-4), with g++ 12:
//   g++ -O2 -std=c++17 -I <eigen3 include dir> eigen34_solver_probe.cpp -o eigen34_solver_probe
#include <Eigen/Eigenvalues>
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
  std::vector<float> out(n * 25, 0.0f);
  for (std::size_t k = 0; k < n; ++k) {
    Eigen::Matrix3f m;
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) m(r, c) = in[k * 9 + r * 3 + c];
    Eigen::EigenSolver<Eigen::Matrix3f> es(m);
    float* o = &out[k * 25];
    if (es.info() != Eigen::Success) continue;  // status 0, zeros
    o[0] = 1.0f;
    const Eigen::EigenSolver<Eigen::Matrix3f>::EigenvalueType ev = es.eigenvalues();
    const Eigen::EigenSolver<Eigen::Matrix3f>::EigenvectorsType v = es.eigenvectors();
    for (int i = 0; i < 3; ++i) {
      o[1 + i] = ev(i).real();
      o[4 + i] = ev(i).imag();
    }
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) {
        o[7 + r * 3 + c] = v(r, c).real();
        o[16 + r * 3 + c] = v(r, c).imag();
      }
  }
  f = std::fopen(argv[2], "wb");
  if (!f) return 1;
  std::fwrite(out.data(), sizeof(float), out.size(), f);
  std::fclose(f);
  return 0;
}
