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
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "stereo_depth_node.h"
#include "thicket/common/loop.h"
#include "thicket/common/node_main.h"

namespace {

using namespace thicket::stereo_depth;

const char* const kProgram = "thicket-stereo-depth";

const char* const kUsage =
    "usage: thicket-stereo-depth [--config stereo_depth.yaml]\n"
    "       thicket-stereo-depth params\n"
    "       thicket-stereo-depth file (--calib C.yaml | --rectified [--focal F --baseline B])\n"
    "                            --left L.png --right R.png [--disparity-out D.pfm]\n"
    "                            [--depth-out Z.png] [--max-disparity N] [--config FILE]\n";

// The number `text` spells, or NaN.
double parseNumber(const std::string& text) {
  try {
    size_t used = 0;
    const double value = std::stod(text, &used);
    if (used == text.size() && std::isfinite(value)) return value;
  } catch (const std::exception&) {
  }
  return std::nan("");
}

int fileMode(int argc, char** argv) {
  const auto fail = [](const std::string& message) { return thicket::failNode(kProgram, message); };
  std::map<std::string, std::string> values;
  bool rectified = false;
  for (int i = 2; i < argc; ++i) {
    std::string flag = argv[i];
    if (flag == "-h" || flag == "--help") {
      std::printf("%s", kUsage);
      return 0;
    }
    if (flag == "--rectified") {
      rectified = true;
      continue;
    }
    std::string value;
    if (const size_t eq = flag.find('='); eq != std::string::npos) {
      value = flag.substr(eq + 1);
      flag = flag.substr(0, eq);
    } else if (i + 1 < argc) {
      value = argv[++i];
    }
    static const std::vector<std::string> known = {
        "--calib", "--left",     "--right",         "--disparity-out", "--depth-out",
        "--focal", "--baseline", "--max-disparity", "--config"};
    if (std::find(known.begin(), known.end(), flag) == known.end()) {
      return fail("file: unexpected argument '" + flag + "'");
    }
    if (value.empty()) return fail("file: " + flag + " needs a value");
    values[flag] = value;
  }
  const auto has = [&](const char* flag) { return values.count(flag) > 0; };
  if (!has("--left") || !has("--right")) return fail("file: --left and --right are required");
  if (rectified == has("--calib")) return fail("file: give exactly one of --calib and --rectified");
  if (!has("--disparity-out") && !has("--depth-out")) {
    return fail("file: nothing to write (give --disparity-out and/or --depth-out)");
  }
  StereoDepthNodeOptions node_options;
  if (has("--config")) {
    try {
      node_options = thicket::loadParams<StereoDepthNodeOptions>(values["--config"]);
    } catch (const thicket::ParamError& e) {
      return fail(e.what());
    }
  }
  StereoDepthOptions options = node_options.stereo;
  options.calibration_file = has("--calib") ? values["--calib"] : "";
  options.rectified = {};
  if (has("--focal") || has("--baseline")) {
    if (!rectified) return fail("file: --focal and --baseline go with --rectified");
    const double focal = has("--focal") ? parseNumber(values["--focal"]) : std::nan("");
    const double baseline = has("--baseline") ? parseNumber(values["--baseline"]) : std::nan("");
    if (!(focal > 0)) return fail("file: --focal needs a positive number [pixels]");
    if (!(baseline > 0)) return fail("file: --baseline needs a positive number [m]");
    options.rectified.fx = focal;
    options.rectified.baseline = baseline;
  }
  if (rectified && has("--depth-out") && options.rectified.fx <= 0) {
    return fail("file: --depth-out of a rectified pair needs --focal and --baseline");
  }
  if (has("--max-disparity")) {
    const double n = parseNumber(values["--max-disparity"]);
    if (!(n >= 1 && n <= 1024) || n != std::floor(n)) {
      return fail("file: --max-disparity needs an integer in [1, 1024]");
    }
    // The search covers [min_disparity, min_disparity + num_disparities): round up to 16.
    const int needed = static_cast<int>(n) + 1 - options.matcher.min_disparity;
    options.matcher.num_disparities = std::max(16, (needed + 15) / 16 * 16);
  }
  auto pipeline = StereoDepth::create(options);
  if (!pipeline) return fail(pipeline.error());
  auto left = readGrayImageFile(values["--left"]);
  if (!left) return fail(left.error());
  auto right = readGrayImageFile(values["--right"]);
  if (!right) return fail(right.error());
  if (left->width != right->width || left->height != right->height) {
    return fail("the images differ in size: left " + std::to_string(left->width) + "x" +
                std::to_string(left->height) + ", right " + std::to_string(right->width) + "x" +
                std::to_string(right->height));
  }
  StereoPair pair;
  pair.rectified = rectified;
  if (pipeline->rectifier())
    pair.calibration_id = pipeline->rectifier()->calibration().calibration_id;
  pair.left = std::move(*left);
  pair.right = std::move(*right);
  auto frame = pipeline->process(pair, thicket::steadyClockMillis);
  if (!frame) return fail(frame.error());
  const int width = pair.left.width;
  const int height = pair.left.height;
  if (has("--disparity-out")) {
    if (auto error = writePfm(values["--disparity-out"], width, height, frame->disparity);
        !error.empty()) {
      return fail(error);
    }
  }
  if (has("--depth-out")) {
    if (auto error = writeDepthPngMm(values["--depth-out"], width, height, frame->depth);
        !error.empty()) {
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
  if (argc >= 2 && std::string(argv[1]) == "file") return fileMode(argc, argv);
  thicket::NodeArgs args;
  StereoDepthNodeOptions options;
  if (auto exit_code = thicket::startNode(argc, argv, kProgram, kUsage, args, options)) {
    return *exit_code;
  }
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
