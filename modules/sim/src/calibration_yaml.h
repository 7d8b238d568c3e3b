// The stereo calibration's id rule, shared by StereoRenderer and its calibrationYaml writer.
#pragma once

#include <string>

namespace thicket::sim {

// Whether id names a calibration: non-empty and made of [A-Za-z0-9_.-].
bool validCalibrationId(const std::string& id);

}  // namespace thicket::sim
