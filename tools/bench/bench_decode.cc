// What checking a message against the schema before LCM's generated decoder (decodeMessage,
// node.h) costs every subscriber: the ESDF snapshot of the forest50 flight's map (bench_worlds.h)
// at 0.10 m voxels, decoded with the check (Arg 1) and by the generated decoder alone (Arg 0).
// Reported per message, with its size and block count as counters.
#include <vector>

#include <benchmark/benchmark.h>

#include <thicket/map_update_t.hpp>

#include "bench_worlds.h"
#include "thicket/common/map_update.h"
#include "thicket/common/node.h"
#include "thicket/mapper/esdf_integrator.h"
#include "thicket/mapper/tsdf_integrator.h"

namespace thicket::bench {
namespace {

// The encoded parts of the ESDF snapshot after the whole flight.
const std::vector<std::vector<uint8_t>>& snapshotMessages() {
  static const std::vector<std::vector<uint8_t>> messages = [] {
    const mapper::TsdfIntegrator tsdf_integrator{mapper::TsdfIntegratorOptions{}};
    mapper::EsdfIntegrator esdf_integrator{mapper::EsdfIntegratorOptions{}};
    esdf_integrator.setInitialPosition(flightFrames().front().world_T_body.position);
    TsdfLayer tsdf(0.1);
    EsdfLayer esdf(0.1);
    for (const FlightFrame& frame : flightFrames()) {
      const auto changed = tsdf_integrator.integrate(frame.image, frame.world_T_camera, tsdf);
      esdf_integrator.update(tsdf, changed, frame.world_T_body.position, esdf);
    }
    std::vector<std::vector<uint8_t>> encoded;
    for (const map_update_t& part : encodeMapUpdate(esdf, {1, 1, 1, true}, {}, {})) {
      std::vector<uint8_t> bytes(static_cast<size_t>(part.getEncodedSize()));
      part.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
      encoded.push_back(std::move(bytes));
    }
    return encoded;
  }();
  return messages;
}

void BM_DecodeMapSnapshot(benchmark::State& state) {
  const bool checked = state.range(0) != 0;
  const std::vector<std::vector<uint8_t>>& messages = snapshotMessages();
  size_t bytes = 0;
  int64_t blocks = 0;
  for (auto _ : state) {
    bytes = 0;
    blocks = 0;
    for (const std::vector<uint8_t>& message : messages) {
      map_update_t msg;
      if (checked) {
        if (!decodeMessage(message.data(), message.size(), msg).empty()) state.SkipWithError("");
      } else {
        msg.decode(message.data(), 0, static_cast<int>(message.size()));
      }
      bytes += message.size();
      blocks += msg.num_blocks;
      benchmark::DoNotOptimize(msg);
    }
  }
  state.counters["KiB"] = static_cast<double>(bytes) / 1024.0;
  state.counters["blocks"] = static_cast<double>(blocks);
  state.counters["messages"] = static_cast<double>(messages.size());
}
BENCHMARK(BM_DecodeMapSnapshot)->Arg(0)->Arg(1)->Unit(benchmark::kMicrosecond);

}  // namespace
}  // namespace thicket::bench
