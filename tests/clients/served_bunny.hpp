// The mesh the clients' tests serve as "bunny": the built-in one, or a generated stand-in of the same
// name when the models are not prepared (scripts/prepare-models.sh).
#pragma once

#include <gtest/gtest.h>

#include <filesystem>

#include "core/eval/mesh_gen.hpp"
#include "core/io/mesh_io.hpp"
#include "tests/core/test_meshes.hpp"

namespace mtlod::test {

// Puts bunny.ply into `dir` and returns its path.
inline std::filesystem::path put_bunny(const std::filesystem::path& dir) {
  const auto bunny = models_dir() / "bunny.ply", to = dir / "bunny.ply";
  if (std::filesystem::exists(bunny)) {
    std::filesystem::copy_file(bunny, to, std::filesystem::copy_options::overwrite_existing);
  } else {
    core::eval::GenerateOptions o;
    o.target_triangles = 4000;
    EXPECT_TRUE(core::io::save_mesh(to, core::eval::generate_mesh(o)).ok());
  }
  return to;
}

}  // namespace mtlod::test
