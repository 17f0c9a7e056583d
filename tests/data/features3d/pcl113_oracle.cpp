#include <pcl/point_types.h>
#include <pcl/features/rops_estimation.h>
#include <pcl/features/fpfh.h>
#include <pcl/search/kdtree.h>
#include <fstream>
#include <sstream>
#include <cstdio>
#include <string>
using namespace pcl;
static void load_xyz(const char* path, PointCloud<PointXYZ>& c, PointCloud<Normal>* n) {
  std::ifstream f(path); std::string line; bool data=false;
  while (std::getline(f, line)) {
    if (!data) { if (line.rfind("DATA", 0) == 0) data = true; continue; }
    std::istringstream ss(line); PointXYZ p; ss >> p.x >> p.y >> p.z; c.push_back(p);
    if (n) { Normal q; ss >> q.normal_x >> q.normal_y >> q.normal_z >> q.curvature; n->push_back(q); }
  }
}
int main(int argc, char** argv) {
  std::string mode = argv[1];
  if (mode == "rops") {
    PointCloud<PointXYZ>::Ptr cloud(new PointCloud<PointXYZ>); load_xyz(argv[2], *cloud, nullptr);
    IndicesPtr idx(new Indices); { std::ifstream f(argv[3]); int i; while (f >> i) idx->push_back(i - 1); }
    std::vector<Vertices> tris; { std::ifstream f(argv[4]); int a,b,c; while (f >> a >> b >> c) { Vertices v; v.vertices = {uint32_t(a-1),uint32_t(b-1),uint32_t(c-1)}; tris.push_back(v);} }
    float support_radius = 0.0285f;
    ROPSEstimation<PointXYZ, Histogram<135>> est;
    search::KdTree<PointXYZ>::Ptr tree(new search::KdTree<PointXYZ>);
    est.setSearchMethod(tree); est.setSearchSurface(cloud); est.setInputCloud(cloud); est.setIndices(idx);
    est.setTriangles(tris); est.setRadiusSearch(support_radius); est.setNumberOfPartitionBins(5);
    est.setNumberOfRotations(3); est.setSupportRadius(support_radius);
    PointCloud<Histogram<135>> out; est.compute(out);
    for (auto& h : out) { for (int i = 0; i < 135; ++i) std::printf("%.9g ", h.histogram[i]); std::printf("\n"); }
  } else if (mode == "fpfh") {
    PointCloud<PointXYZ>::Ptr cloud(new PointCloud<PointXYZ>); PointCloud<Normal>::Ptr nrm(new PointCloud<Normal>);
    load_xyz(argv[2], *cloud, nrm.get());
    double r = std::atof(argv[3]);
    FPFHEstimation<PointXYZ, Normal, FPFHSignature33> est;
    search::KdTree<PointXYZ>::Ptr tree(new search::KdTree<PointXYZ>(false));
    est.setSearchMethod(tree); est.setInputCloud(cloud); est.setInputNormals(nrm);
    if (r > 0) est.setRadiusSearch(r); else est.setKSearch(int(-r));
    PointCloud<FPFHSignature33> out; est.compute(out);
    for (auto& h : out) { for (int i = 0; i < 33; ++i) std::printf("%.9g ", h.histogram[i]); std::printf("\n"); }
  }
  return 0;
}
