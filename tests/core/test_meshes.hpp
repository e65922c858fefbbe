// Small meshes with known properties and the locations of the test data, shared by core tests.
#pragma once

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "core/model/mesh.hpp"

namespace mtlod::test {

// The shared real scans (see their README); tests GTEST_SKIP when the folder is absent.
inline std::filesystem::path shared_meshes_dir() {
  return MTLOD_SHARED_MESHES_DIR;
}
// Built-in models written by scripts/prepare-models.sh.
inline std::filesystem::path models_dir() {
  return MTLOD_MODELS_DIR;
}

// A fresh, empty directory for files a test writes; per process, since ctest runs tests in parallel.
inline std::filesystem::path scratch_dir(const std::string& name) {
  auto dir =
      std::filesystem::temp_directory_path() / ("mtlod-test-" + name + "-" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  // Removed when the test process ends.
  struct Cleanup {
    std::vector<std::filesystem::path> dirs;
    ~Cleanup() {
      std::error_code ignored;
      for (const auto& d : dirs) std::filesystem::remove_all(d, ignored);
    }
  };
  static Cleanup cleanup;
  cleanup.dirs.push_back(dir);
  return dir;
}

// A file's bytes, and a file written with given bytes (test inputs made by hand).
inline std::string read_file(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}
inline void write_file(const std::filesystem::path& path, const std::string& bytes) {
  std::ofstream(path, std::ios::binary) << bytes;
}

// Regular tetrahedron, outward: closed 2-manifold, V=4 E=6 F=4, Euler characteristic 2.
inline core::model::Mesh tetrahedron() {
  core::model::Mesh m;
  m.positions = {1, 1, 1, 1, -1, -1, -1, 1, -1, -1, -1, 1};
  m.triangles = {0, 1, 2, 0, 3, 1, 0, 2, 3, 1, 3, 2};
  return m;
}

// Unit square in z=0 as two triangles: one boundary loop of 4 edges, 5 edges, Euler characteristic 1.
inline core::model::Mesh square() {
  core::model::Mesh m;
  m.positions = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0};
  m.triangles = {0, 1, 2, 0, 2, 3};
  return m;
}

}  // namespace mtlod::test
