// PNG output for thicket-sim render (the only place the simulator touches OpenCV).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace thicket::sim {

/// Writes depth in metres as a 16-bit PNG in millimetres (0 = no return; beyond 65.535 m: 0).
/// Returns an error text, empty on success (also when the pixels do not fill width x height).
std::string writeDepthPng(const std::string& path, int width, int height,
                          const std::vector<float>& depth_m);
/// Writes an 8-bit grayscale PNG.
std::string writeGrayPng(const std::string& path, int width, int height,
                         const std::vector<uint8_t>& pixels);

}  // namespace thicket::sim
