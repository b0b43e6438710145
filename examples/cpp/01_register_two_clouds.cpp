// 01: register two clouds with scanalign's engine, and with stock PCL ICP using
// scanalign's PCL plug-ins. Exits non-zero if either misses the known motion.
#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include <Eigen/Geometry>
#include <pcl/point_types.h>
#include <pcl/registration/icp.h>

#include <scanalign/features/normals.hpp>
#include <scanalign/registration/icp.hpp>
#include <scanalign/registration/pcl/box_rejector.hpp>
#include <scanalign/registration/pcl/point_to_plane_lls.hpp>

int main() {
  // Model: a bumpy 20 x 20 cm surface 60 cm in front of the camera, in metres.
  std::mt19937 rng(0);
  std::uniform_real_distribution<float> u(-0.1f, 0.1f);
  std::vector<float> model;
  for (int i = 0; i < 40000; ++i) {
    const float x = u(rng), y = u(rng);
    model.insert(model.end(), {x, y, 0.6f + 0.01f * std::sin(40 * x) * std::cos(30 * y) + 0.3f * x * y});
  }
  const scanalign::CloudView<float> model_view(model.data(), model.size() / 3);
  std::vector<float> normals(model.size());
  scanalign::estimateNormals(model_view, scanalign::NormalEstimationSettings{}, normals.data());

  // The new frame sees the model moved by T_true^-1.
  const Eigen::Affine3d T_true = Eigen::Translation3d(0.005, -0.004, 0.003) *
                                 Eigen::AngleAxisd(0.03, Eigen::Vector3d(1, 2, 3).normalized());
  std::vector<float> frame(model.size());
  for (std::size_t i = 0; i < model.size() / 3; ++i) {
    const Eigen::Vector3d p = T_true.inverse() * Eigen::Vector3d(model[3 * i], model[3 * i + 1], model[3 * i + 2]);
    for (int k = 0; k < 3; ++k) frame[3 * i + k] = float(p[k]);
  }

  scanalign::IcpSettings settings;  // seed defaults: point-to-plane LLS, 50 iterations, eps 1e-8
  settings.box = scanalign::Box::freeHandPreset();
  scanalign::Icp<float> icp(settings);
  icp.setTarget(model_view, scanalign::CloudView<float>(normals.data(), normals.size() / 3));
  const scanalign::IcpResult r = icp.align(scanalign::CloudView<float>(frame.data(), frame.size() / 3));
  const double err_engine = (r.T_target_source - T_true.matrix()).cwiseAbs().maxCoeff();
  std::printf("engine: %s after %d iterations, fitness %.3f, rmse %.2e m, |T - T_true| %.2e\n",
              scanalign::toString(r.status), r.iterations, r.fitness, r.inlier_rmse, err_engine);

  // The same through stock PCL with scanalign's plug-ins.
  auto src = pcl::make_shared<pcl::PointCloud<pcl::PointNormal>>();
  auto tgt = pcl::make_shared<pcl::PointCloud<pcl::PointNormal>>();
  for (std::size_t i = 0; i < model.size() / 3; ++i) {
    pcl::PointNormal s, t;
    s.x = frame[3 * i], s.y = frame[3 * i + 1], s.z = frame[3 * i + 2];
    t.x = model[3 * i], t.y = model[3 * i + 1], t.z = model[3 * i + 2];
    t.normal_x = normals[3 * i], t.normal_y = normals[3 * i + 1], t.normal_z = normals[3 * i + 2];
    if (std::isfinite(t.normal_x)) src->push_back(s), tgt->push_back(t);
  }
  pcl::IterativeClosestPointWithNormals<pcl::PointNormal, pcl::PointNormal> pcl_icp;
  pcl_icp.setTransformationEstimation(
      pcl::make_shared<scanalign::PointToPlaneLLS<pcl::PointNormal, pcl::PointNormal>>());
  auto box = pcl::make_shared<scanalign::BoxRejector>(scanalign::Box::freeHandPreset());
  box->setInputSource<pcl::PointNormal>(src);
  pcl_icp.addCorrespondenceRejector(box);
  pcl_icp.setMaxCorrespondenceDistance(0.05);
  pcl_icp.setTransformationEpsilon(1e-8);
  pcl_icp.setEuclideanFitnessEpsilon(1e-8);
  pcl_icp.setInputSource(src);
  pcl_icp.setInputTarget(tgt);
  pcl::PointCloud<pcl::PointNormal> aligned;
  pcl_icp.align(aligned);
  const double err_pcl = (pcl_icp.getFinalTransformation().cast<double>() - T_true.matrix()).cwiseAbs().maxCoeff();
  std::printf("stock PCL ICP + scanalign::PointToPlaneLLS + BoxRejector: converged %d, |T - T_true| %.2e\n",
              int(pcl_icp.hasConverged()), err_pcl);
  return (r.converged && err_engine < 1e-4 && err_pcl < 1e-4) ? 0 : 1;
}
