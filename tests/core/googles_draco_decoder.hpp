// Google's own decoder on a payload, as a user of the server would run it: the bytes go to
// DIR/NAME.drc, `draco_decoder` (Debian package draco) writes DIR/NAME.ply, which is loaded as it
// is (no clean-up). Its output goes to DIR/NAME.log.
#pragma once

#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <span>
#include <string>

#include "core/io/mesh_io.hpp"
#include "core/result.hpp"

namespace mtlod::test {

inline Result<core::model::Mesh> googles_draco_decode(std::span<const std::uint8_t> bytes,
                                                      const std::filesystem::path& dir,
                                                      const std::string& name) {
  const auto drc = dir / (name + ".drc"), ply = dir / (name + ".ply"), log = dir / (name + ".log");
  std::ofstream(drc, std::ios::binary)
      .write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
  const std::string command =
      "draco_decoder -i " + drc.string() + " -o " + ply.string() + " > " + log.string() + " 2>&1";
  if (std::system(command.c_str()) != 0) {
    return make_error(ErrorCode::kInternal,
                      "draco_decoder (Debian package draco) failed or is missing, see " + log.string());
  }
  MTLOD_TRY(core::io::LoadedMesh loaded, core::io::load_mesh(ply, {.clean = false}));
  return std::move(loaded.mesh);
}

}  // namespace mtlod::test
