#include "thicket/stereo_depth/calibration.h"

#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>

#include <Eigen/LU>
#include <opencv2/core.hpp>
#include <opencv2/core/eigen.hpp>

namespace thicket::stereo_depth {
namespace {

bool allFinite(const std::vector<double>& values) {
  for (double v : values) {
    if (!std::isfinite(v)) return false;
  }
  return true;
}

std::string checkCameraMatrix(const char* name, const Eigen::Matrix3d& k) {
  if (!k.allFinite()) return std::string(name) + " has non-finite entries";
  if (k(1, 0) != 0 || k(2, 0) != 0 || k(2, 1) != 0 || k(2, 2) != 1) {
    return std::string(name) + " is not a camera matrix [fx s cx; 0 fy cy; 0 0 1]";
  }
  if (k(0, 0) <= 0 || k(1, 1) <= 0) return std::string(name) + " has a non-positive focal length";
  return {};
}

std::string checkDistortion(const char* name, const std::vector<double>& d) {
  const size_t n = d.size();
  if (n != 4 && n != 5 && n != 8 && n != 12 && n != 14) {
    return std::string(name) + " has " + std::to_string(n) +
           " coefficients (OpenCV takes 4, 5, 8, 12 or 14)";
  }
  if (!allFinite(d)) return std::string(name) + " has non-finite coefficients";
  return {};
}

// A matrix entry of the file as rows x cols doubles, or why not.
Expected<cv::Mat> readMatrix(const cv::FileStorage& fs, const std::string& source,
                             const char* key) {
  const cv::FileNode node = fs[key];
  if (node.empty() || node.isNone()) {
    return unexpected(source + ": missing key '" + std::string(key) + "'");
  }
  cv::Mat m;
  try {
    node >> m;
  } catch (const cv::Exception& e) {
    return unexpected(source + ": key '" + key + "' is not a matrix: " + e.err);
  }
  if (m.empty()) return unexpected(source + ": key '" + key + "' is not a matrix");
  if (m.channels() != 1) return unexpected(source + ": key '" + key + "' has several channels");
  cv::Mat d;
  m.convertTo(d, CV_64F);
  return d;
}

Expected<Eigen::Matrix3d> read3x3(const cv::FileStorage& fs, const std::string& source,
                                  const char* key) {
  auto m = readMatrix(fs, source, key);
  if (!m) return unexpected(m.error());
  if (m->rows != 3 || m->cols != 3) {
    return unexpected(source + ": key '" + key + "' is " + std::to_string(m->rows) + "x" +
                      std::to_string(m->cols) + ", expected 3x3");
  }
  Eigen::Matrix3d out;
  cv::cv2eigen(*m, out);
  return out;
}

Expected<std::vector<double>> readVector(const cv::FileStorage& fs, const std::string& source,
                                         const char* key) {
  auto m = readMatrix(fs, source, key);
  if (!m) return unexpected(m.error());
  if (m->rows != 1 && m->cols != 1) {
    return unexpected(source + ": key '" + key + "' is " + std::to_string(m->rows) + "x" +
                      std::to_string(m->cols) + ", expected a row or a column");
  }
  std::vector<double> out;
  for (int i = 0; i < static_cast<int>(m->total()); ++i) out.push_back(m->at<double>(i));
  return out;
}

Expected<int> readInt(const cv::FileStorage& fs, const std::string& source, const char* key) {
  const cv::FileNode node = fs[key];
  if (node.empty() || node.isNone()) {
    return unexpected(source + ": missing key '" + std::string(key) + "'");
  }
  if (!node.isInt()) return unexpected(source + ": key '" + key + "' is not an integer");
  return static_cast<int>(node);
}

void writeMatrix(std::ostream& out, const char* name, int rows, int cols, const double* data) {
  out << name << ": !!opencv-matrix\n   rows: " << rows << "\n   cols: " << cols
      << "\n   dt: d\n   data: [ ";
  for (int i = 0; i < rows * cols; ++i) {
    char number[32];
    // Non-finite values as FileStorage writes them, so that they read back (and are refused).
    if (std::isnan(data[i])) {
      std::snprintf(number, sizeof(number), ".Nan");
    } else if (std::isinf(data[i])) {
      std::snprintf(number, sizeof(number), data[i] > 0 ? ".Inf" : "-.Inf");
    } else {
      std::snprintf(number, sizeof(number), "%.17g", data[i]);
    }
    out << (i > 0 ? ", " : "") << number;
  }
  out << " ]\n";
}

}  // namespace

Expected<StereoCalibration> StereoCalibration::validated() const {
  if (width < 1 || height < 1 || width > 16384 || height > 16384) {
    return unexpected("image size " + std::to_string(width) + "x" + std::to_string(height) +
                      " is outside [1, 16384]");
  }
  for (const std::string& e : {checkCameraMatrix("camera_matrix_left", camera_matrix_left),
                               checkCameraMatrix("camera_matrix_right", camera_matrix_right),
                               checkDistortion("distortion_left", distortion_left),
                               checkDistortion("distortion_right", distortion_right)}) {
    if (!e.empty()) return unexpected(e);
  }
  if (!R.allFinite()) return unexpected("R has non-finite entries");
  if ((R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() > 1e-6 ||
      R.determinant() < 0) {
    return unexpected("R is not a rotation matrix");
  }
  if (!T.allFinite()) return unexpected("T has non-finite entries");
  if (T.norm() < 1e-3) return unexpected("the baseline |T| is zero (below 1 mm)");
  return *this;
}

Expected<StereoCalibration> parseStereoCalibration(const std::string& yaml,
                                                   const std::string& source) {
  cv::FileStorage fs;
  try {
    if (!fs.open(yaml,
                 cv::FileStorage::READ | cv::FileStorage::MEMORY | cv::FileStorage::FORMAT_YAML)) {
      return unexpected(source + ": not OpenCV FileStorage YAML");
    }
  } catch (const cv::Exception& e) {
    return unexpected(source + ": not OpenCV FileStorage YAML: " + e.err);
  }
  StereoCalibration c;
  const cv::FileNode id = fs["calibration_id"];
  if (!id.empty() && !id.isNone()) {
    if (!id.isString()) return unexpected(source + ": key 'calibration_id' is not a string");
    c.calibration_id = static_cast<std::string>(id);
  }
  auto width = readInt(fs, source, "image_width");
  if (!width) return unexpected(width.error());
  auto height = readInt(fs, source, "image_height");
  if (!height) return unexpected(height.error());
  c.width = *width;
  c.height = *height;
  auto kl = read3x3(fs, source, "camera_matrix_left");
  if (!kl) return unexpected(kl.error());
  auto kr = read3x3(fs, source, "camera_matrix_right");
  if (!kr) return unexpected(kr.error());
  auto dl = readVector(fs, source, "distortion_left");
  if (!dl) return unexpected(dl.error());
  auto dr = readVector(fs, source, "distortion_right");
  if (!dr) return unexpected(dr.error());
  auto r = read3x3(fs, source, "R");
  if (!r) return unexpected(r.error());
  auto t = readVector(fs, source, "T");
  if (!t) return unexpected(t.error());
  if (t->size() != 3) {
    return unexpected(source + ": key 'T' has " + std::to_string(t->size()) +
                      " entries, expected 3");
  }
  c.camera_matrix_left = *kl;
  c.camera_matrix_right = *kr;
  c.distortion_left = *dl;
  c.distortion_right = *dr;
  c.R = *r;
  c.T = Eigen::Vector3d((*t)[0], (*t)[1], (*t)[2]);
  auto valid = c.validated();
  if (!valid) return unexpected(source + ": " + valid.error());
  return c;
}

Expected<StereoCalibration> loadStereoCalibration(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return unexpected(path + ": cannot read the calibration file");
  std::ostringstream text;
  text << in.rdbuf();
  if (text.str().empty()) return unexpected(path + ": the calibration file is empty");
  return parseStereoCalibration(text.str(), path);
}

std::string stereoCalibrationYaml(const StereoCalibration& c) {
  std::ostringstream out;
  out << "%YAML:1.0\n---\n";
  if (!c.calibration_id.empty()) out << "calibration_id: \"" << c.calibration_id << "\"\n";
  out << "image_width: " << c.width << "\nimage_height: " << c.height << "\n";
  const Eigen::Matrix<double, 3, 3, Eigen::RowMajor> kl = c.camera_matrix_left;
  const Eigen::Matrix<double, 3, 3, Eigen::RowMajor> kr = c.camera_matrix_right;
  const Eigen::Matrix<double, 3, 3, Eigen::RowMajor> r = c.R;
  writeMatrix(out, "camera_matrix_left", 3, 3, kl.data());
  writeMatrix(out, "distortion_left", 1, static_cast<int>(c.distortion_left.size()),
              c.distortion_left.data());
  writeMatrix(out, "camera_matrix_right", 3, 3, kr.data());
  writeMatrix(out, "distortion_right", 1, static_cast<int>(c.distortion_right.size()),
              c.distortion_right.data());
  writeMatrix(out, "R", 3, 3, r.data());
  writeMatrix(out, "T", 3, 1, c.T.data());
  return out.str();
}

}  // namespace thicket::stereo_depth
