// StereoRenderer::calibrationYaml: the simulated pair's calibration as OpenCV FileStorage YAML.
#include "calibration_yaml.h"

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <ostream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "thicket/sim/render.h"

namespace thicket::sim {
namespace {

void writeMatrix(std::ostream& out, const std::string& name, int rows, int cols,
                 const std::vector<double>& row_major) {
  out << name << ": !!opencv-matrix\n   rows: " << rows << "\n   cols: " << cols
      << "\n   dt: d\n   data: [ ";
  for (size_t i = 0; i < row_major.size(); ++i) {
    char number[32];
    std::snprintf(number, sizeof(number), "%.16e", row_major[i]);  // as cv::FileStorage writes
    out << (i > 0 ? ", " : "") << number;
  }
  out << " ]\n";
}

}  // namespace

bool validCalibrationId(const std::string& id) {
  return !id.empty() && std::all_of(id.begin(), id.end(), [](char ch) {
    return std::isalnum(static_cast<unsigned char>(ch)) || ch == '_' || ch == '.' || ch == '-';
  });
}

std::string StereoRenderer::calibrationYaml(const std::string& id) const {
  if (!validCalibrationId(id)) {
    throw std::invalid_argument("calibrationYaml: the id must be non-empty [A-Za-z0-9_.-]");
  }
  const PinholeCamera& c = camera_;
  const std::vector<double> camera_matrix = {c.fx, 0, c.cx, 0, c.fy, c.cy, 0, 0, 1};
  const std::vector<double> no_distortion(5, 0.0);
  std::ostringstream out;
  out << "%YAML:1.0\n---\n";
  out << "calibration_id: \"" << id << "\"\n";
  out << "image_width: " << c.width << "\nimage_height: " << c.height << "\n";
  writeMatrix(out, "camera_matrix_left", 3, 3, camera_matrix);
  writeMatrix(out, "distortion_left", 1, 5, no_distortion);
  writeMatrix(out, "camera_matrix_right", 3, 3, camera_matrix);
  writeMatrix(out, "distortion_right", 1, 5, no_distortion);
  writeMatrix(out, "R", 3, 3, {1, 0, 0, 0, 1, 0, 0, 0, 1});
  // cv::stereoCalibrate's T maps left-camera coordinates into the right camera: x_r = R x_l + T.
  writeMatrix(out, "T", 3, 1, {-options_.baseline, 0, 0});
  return out.str();
}

}  // namespace thicket::sim
