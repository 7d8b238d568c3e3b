// thicket-stereo-depth: stereo pairs to depth images.
//
//   thicket-stereo-depth [--lcm-url URL] [--config stereo_depth.yaml]   (the node: STEREO in,
//                                                                        CAMERA_DEPTH out)
//   thicket-stereo-depth params        (every option of --config, with its default)
//   thicket-stereo-depth file (--calib C.yaml | --rectified [--focal F --baseline B])
//                        --left L.png --right R.png [--disparity-out D.pfm] [--depth-out Z.png]
//                        [--max-disparity N] [--config stereo_depth.yaml]
//       offline, on image files: disparity as PFM in pixels of the (rectified) left image, 0 where
//       invalid; depth as a 16-bit PNG in millimetres, 0 where invalid.
//   thicket-stereo-depth calibrate --left L1 L2 ... --right R1 R2 ... --corners 9 6
//                        --square 0.025 [--id NAME] --out calibration.yaml
//       the calibration the node reads (calibration_file), from chessboard views; prints the
//       reprojection errors.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "stereo_depth_node.h"
#include "thicket/common/cli.h"
#include "thicket/common/loop.h"
#include "thicket/common/node_main.h"
#include "thicket/stereo_depth/calibrate.h"

namespace {

using namespace thicket::stereo_depth;

const char* const kProgram = "thicket-stereo-depth";

const char* const kUsage =
    "thicket-stereo-depth: stereo pairs to depth images. The node takes STEREO and publishes\n"
    "CAMERA_DEPTH; `file` runs the same pipeline on image files, `calibrate` writes the\n"
    "calibration file from chessboard views.";

// The arguments of the `file` command.
struct FileArgs {
  std::string calib, left, right, disparity_out, depth_out, config;
  bool rectified = false;
  std::optional<double> focal, baseline;
  std::optional<int> max_disparity;
};

void addFileFlags(CLI::App& file, FileArgs& a) {
  using thicket::cli::nonEmpty;
  const double inf = std::numeric_limits<double>::infinity();
  file.add_option("--left", a.left, "left image (PNG or PGM, 8-bit gray)")
      ->required()
      ->check(nonEmpty());
  file.add_option("--right", a.right, "right image")->required()->check(nonEmpty());
  CLI::Option* calib =
      file.add_option("--calib", a.calib, "calibration (YAML) to rectify with")->check(nonEmpty());
  CLI::Option* rectified =
      file.add_flag("--rectified", a.rectified, "the pair is already rectified")->excludes(calib);
  CLI::Option* focal = file.add_option("--focal", a.focal, "focal length of a rectified pair [px]")
                           ->check(thicket::cli::number(std::nextafter(0.0, 1.0), inf))
                           ->needs(rectified);
  file.add_option("--baseline", a.baseline, "baseline of a rectified pair [m]")
      ->check(thicket::cli::number(std::nextafter(0.0, 1.0), inf))
      ->needs(rectified)
      ->needs(focal);
  focal->needs("--baseline");
  file.add_option("--disparity-out", a.disparity_out,
                  "disparity as PFM, in pixels of the (rectified) left image, 0 where invalid")
      ->check(nonEmpty());
  file.add_option("--depth-out", a.depth_out,
                  "depth as a 16-bit PNG in millimetres, 0 where invalid")
      ->check(nonEmpty());
  file.add_option("--max-disparity", a.max_disparity, "largest disparity searched [px]")
      ->check(thicket::cli::integer(1, 1024));
  file.add_option("--config", a.config, "parameter file (YAML), as the node's")->check(nonEmpty());
}

// The arguments of the `calibrate` command.
struct CalibrateArgs {
  std::vector<std::string> left, right;
  std::vector<int> corners;
  double square = 0;
  std::string id, out;
};

void addCalibrateFlags(CLI::App& calibrate, CalibrateArgs& a) {
  using thicket::cli::nonEmpty;
  calibrate.add_option("--left", a.left, "the left camera's views of the board, in order")
      ->required()
      ->check(nonEmpty());
  calibrate.add_option("--right", a.right, "the right camera's views, in the same order")
      ->required()
      ->check(nonEmpty());
  calibrate.add_option("--corners", a.corners, "inner corners of the board: columns rows")
      ->required()
      ->expected(2)
      ->check(thicket::cli::integer(2, 1000));
  calibrate
      .add_option("--square", a.square, "side of one square of the board [m] (the scale of T)")
      ->required()
      ->check(thicket::cli::number(std::nextafter(0.0, 1.0), 10.0));
  calibrate.add_option("--id", a.id, "calibration_id the pairs must carry (default: none)");
  calibrate.add_option("--out", a.out, "the calibration file to write (YAML)")
      ->required()
      ->check(nonEmpty());
}

int calibrateMode(const CalibrateArgs& a) {
  const auto fail = [](const std::string& message) { return thicket::failNode(kProgram, message); };
  if (a.left.size() != a.right.size()) {
    return fail("calibrate: " + std::to_string(a.left.size()) + " left and " +
                std::to_string(a.right.size()) + " right images: give them in pairs");
  }
  std::vector<GrayPair> pairs;
  for (size_t i = 0; i < a.left.size(); ++i) {
    auto left = readGrayImageFile(a.left[i]);
    if (!left) return fail(left.error());
    auto right = readGrayImageFile(a.right[i]);
    if (!right) return fail(right.error());
    pairs.push_back({a.left[i], std::move(*left), std::move(*right)});
  }
  const auto result = calibrateStereo(pairs, {a.corners.at(0), a.corners.at(1), a.square}, a.id);
  if (!result) return fail("calibrate: " + result.error());
  for (const std::string& skipped : result->pairs_skipped) {
    std::printf("%s: skipped %s\n", kProgram, skipped.c_str());
  }
  {
    std::ofstream file(a.out, std::ios::binary | std::ios::trunc);
    file << stereoCalibrationYaml(result->calibration);
    if (!file.flush()) return fail("calibrate: cannot write " + a.out);
  }
  const StereoCalibration& c = result->calibration;
  std::printf(
      "%s: wrote %s from %d of %zu pairs (%dx%d): reprojection error %.3f px left, %.3f px "
      "right, %.3f px stereo; epipolar error %.3f px; focal lengths %.1f / %.1f px, baseline "
      "%.4f m\n",
      kProgram, a.out.c_str(), result->pairs_used, pairs.size(), c.width, c.height,
      result->rms_left, result->rms_right, result->rms_stereo, result->epipolar_error,
      c.camera_matrix_left(0, 0), c.camera_matrix_right(0, 0), c.T.norm());
  return 0;
}

int fileMode(const FileArgs& a) {
  const auto fail = [](const std::string& message) { return thicket::failNode(kProgram, message); };
  if (!a.rectified && a.calib.empty()) return fail("file: give one of --calib and --rectified");
  if (a.disparity_out.empty() && a.depth_out.empty()) {
    return fail("file: nothing to write (give --disparity-out and/or --depth-out)");
  }
  StereoDepthNodeOptions node_options;
  if (!a.config.empty()) {
    try {
      node_options = thicket::loadParams<StereoDepthNodeOptions>(a.config);
    } catch (const thicket::ParamError& e) {
      return fail(e.what());
    }
  }
  StereoDepthOptions options = node_options.stereo;
  options.calibration_file = a.calib;
  options.rectified = {};
  if (a.focal && a.baseline) {
    options.rectified.fx = *a.focal;
    options.rectified.baseline = *a.baseline;
  }
  if (a.rectified && !a.depth_out.empty() && options.rectified.fx <= 0) {
    return fail("file: --depth-out of a rectified pair needs --focal and --baseline");
  }
  if (a.max_disparity) {
    // The search covers [min_disparity, min_disparity + num_disparities): round up to 16.
    const int needed = *a.max_disparity + 1 - options.matcher.min_disparity;
    options.matcher.num_disparities = std::max(16, (needed + 15) / 16 * 16);
  }
  auto pipeline = StereoDepth::create(options);
  if (!pipeline) return fail(pipeline.error());
  auto left = readGrayImageFile(a.left);
  if (!left) return fail(left.error());
  auto right = readGrayImageFile(a.right);
  if (!right) return fail(right.error());
  if (left->width != right->width || left->height != right->height) {
    return fail("the images differ in size: left " + std::to_string(left->width) + "x" +
                std::to_string(left->height) + ", right " + std::to_string(right->width) + "x" +
                std::to_string(right->height));
  }
  StereoPair pair;
  pair.rectified = a.rectified;
  if (pipeline->rectifier())
    pair.calibration_id = pipeline->rectifier()->calibration().calibration_id;
  pair.left = std::move(*left);
  pair.right = std::move(*right);
  auto frame = pipeline->process(pair, thicket::steadyClockMillis);
  if (!frame) return fail(frame.error());
  const int width = pair.left.width;
  const int height = pair.left.height;
  if (!a.disparity_out.empty()) {
    if (auto error = writePfm(a.disparity_out, width, height, frame->disparity); !error.empty()) {
      return fail(error);
    }
  }
  if (!a.depth_out.empty()) {
    if (auto error = writeDepthPngMm(a.depth_out, width, height, frame->depth); !error.empty()) {
      return fail(error);
    }
  }
  size_t valid_disparity = 0;
  for (float d : frame->disparity) valid_disparity += d > 0 ? 1 : 0;
  std::printf(
      "%s: %dx%d, %d disparities, valid disparity %.1f %%", kProgram, width, height,
      options.matcher.num_disparities,
      100.0 * static_cast<double>(valid_disparity) / static_cast<double>(frame->disparity.size()));
  if (frame->has_depth) {
    std::printf(", valid depth %.1f %% (f %.2f px, baseline %.4f m)", 100 * frame->validFraction(),
                frame->camera.fx, frame->baseline);
  }
  std::printf("; rectify %.2f ms, match %.2f ms\n", frame->rectify_ms, frame->match_ms);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  thicket::NodeArgs args;
  StereoDepthNodeOptions options;
  FileArgs file_args;
  CalibrateArgs calibrate_args;
  // The app is gone after startNode: its subcommands report by callback.
  bool file_mode = false, calibrate_mode = false;
  if (auto exit_code =
          thicket::startNode(argc, argv, kProgram, kUsage, args, options, [&](CLI::App& app) {
            CLI::App* command = app.add_subcommand(
                "file", "offline, on image files: disparity and/or depth of one stereo pair");
            addFileFlags(*command, file_args);
            command->callback([&file_mode] { file_mode = true; });
            CLI::App* calibrate = app.add_subcommand(
                "calibrate", "the calibration file from chessboard views (cv::stereoCalibrate)");
            addCalibrateFlags(*calibrate, calibrate_args);
            calibrate->callback([&calibrate_mode] { calibrate_mode = true; });
          })) {
    return *exit_code;
  }
  if (file_mode) return fileMode(file_args);
  if (calibrate_mode) return calibrateMode(calibrate_args);
  // Wall-clock time only measures durations; no decision reads it.
  return thicket::runNode(kProgram, args.lcm_url, [&](lcm::LCM& lcm, thicket::Loop& loop) {
    std::unique_ptr<StereoDepthNode> node;
    try {
      node = std::make_unique<StereoDepthNode>(lcm, options, thicket::steadyClockMillis);
    } catch (const std::invalid_argument& e) {
      return thicket::failNode(kProgram, e.what());
    }
    loop.run();
    std::printf("%s: %s\n", kProgram, node->summary().c_str());
    return 0;
  });
}
