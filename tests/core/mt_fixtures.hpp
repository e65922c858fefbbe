// MTs of the test meshes, built once per test binary and shared by its tests (the builder is the
// slow part). Real scans come from the shared meshes folder; null when a file is absent, so tests
// can GTEST_SKIP.
#pragma once

#include <map>
#include <memory>
#include <string>

#include "core/io/mesh_io.hpp"
#include "core/mesh_gen.hpp"
#include "core/mt_builder.hpp"
#include "tests/core/cut_validator.hpp"
#include "tests/core/test_meshes.hpp"

namespace mtlod::test {

struct MtCase {
  core::Mesh mesh;
  core::Mt mt;
  CutReference reference;
};

inline const MtCase* build_case(const std::string& key, core::Mesh mesh) {
  static std::map<std::string, std::unique_ptr<MtCase>> cache;
  auto& slot = cache[key];
  if (!slot) {
    auto c = std::make_unique<MtCase>();
    c->mesh = std::move(mesh);
    auto mt = core::build_mt(c->mesh);
    EXPECT_TRUE(mt.ok()) << key << ": " << (mt.ok() ? "" : mt.error().message);
    if (!mt.ok()) return nullptr;
    c->mt = std::move(mt).value();
    c->reference = make_reference(c->mesh);
    slot = std::move(c);
  }
  return slot.get();
}

// A shared scan, loaded with the default clean-up (as mtlod-build does); null when absent.
inline const MtCase* scan_case(const std::string& file) {
  const auto path = shared_meshes_dir() / file;
  if (!std::filesystem::exists(path)) return nullptr;
  auto loaded = core::io::load_mesh(path);
  EXPECT_TRUE(loaded.ok()) << file;
  if (!loaded.ok()) return nullptr;
  return build_case(file, std::move(loaded->mesh));
}

// A synthetic shape of about the given size.
inline const MtCase* shape_case(core::Shape shape, std::size_t triangles, std::uint32_t seed = 1) {
  core::GenerateOptions options;
  options.shape = shape;
  options.target_triangles = triangles;
  options.seed = seed;
  return build_case("shape" + std::to_string(int(shape)) + "-" + std::to_string(triangles) + "-" + std::to_string(seed),
                    core::generate_mesh(options));
}

}  // namespace mtlod::test
