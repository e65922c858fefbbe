// Mesh reading and writing: exact round trips, every supported format, and corrupt inputs that
// must come back as errors naming the file and the problem.
#include "core/io/mesh_io.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <random>
#include <string>

#include "tests/core/test_meshes.hpp"

namespace mtlod::core::io {
namespace {

namespace fs = std::filesystem;

using test::read_file;
using test::write_file;

// Positions with awkward float values: tiny, huge, negative zero, many significant digits.
model::Mesh awkward_mesh(bool with_attributes) {
  model::Mesh m = test::tetrahedron();
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> any(-1e4f, 1e4f);
  for (float& x : m.positions) x = x * any(rng);
  m.positions[0] = 1e-30f;
  m.positions[1] = 3.4e37f;
  m.positions[2] = 0.1f;
  if (with_attributes) {
    for (int i = 0; i < 12; ++i) m.normals.push_back(std::nextafter(static_cast<float>(i) / 7.0f, 2.0f));
    for (int i = 0; i < 12; ++i) m.colors.push_back(static_cast<std::uint8_t>(i * 21));
  }
  return m;
}

void expect_same_bits(const std::vector<float>& a, const std::vector<float>& b) {
  ASSERT_EQ(a.size(), b.size());
  EXPECT_EQ(std::memcmp(a.data(), b.data(), a.size() * sizeof(float)), 0);
}

io::LoadOptions as_read() {
  io::LoadOptions o;
  o.clean = false;
  return o;
}

TEST(MeshIo, BinaryPlyRoundTripIsBitExactWithNormalsAndColours) {
  const auto dir = test::scratch_dir("ply-roundtrip");
  const model::Mesh m = awkward_mesh(true);
  ASSERT_TRUE(io::save_mesh(dir / "m.ply", m).ok());
  auto loaded = io::load_mesh(dir / "m.ply", as_read());
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  expect_same_bits(loaded->mesh.positions, m.positions);
  expect_same_bits(loaded->mesh.normals, m.normals);
  EXPECT_EQ(loaded->mesh.colors, m.colors);
  EXPECT_EQ(loaded->mesh.triangles, m.triangles);
}

TEST(MeshIo, ObjRoundTripKeepsPositionsExactly) {
  const auto dir = test::scratch_dir("obj-roundtrip");
  const model::Mesh m = awkward_mesh(false);
  ASSERT_TRUE(io::save_mesh(dir / "m.obj", m).ok());
  auto loaded = io::load_mesh(dir / "m.obj", as_read());
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  expect_same_bits(loaded->mesh.positions, m.positions);
  EXPECT_EQ(loaded->mesh.triangles, m.triangles);
}

TEST(MeshIo, ReadsAsciiPlyOffAndObjPolygons) {
  const auto dir = test::scratch_dir("formats");
  write_file(dir / "sq.ply",
             "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
             "element face 1\nproperty list uchar int vertex_indices\nend_header\n"
             "0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n");
  write_file(dir / "sq.off", "OFF\n4 1 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n");
  write_file(dir / "sq.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n");
  for (const char* name : {"sq.ply", "sq.off", "sq.obj"}) {
    auto loaded = io::load_mesh(dir / name);
    ASSERT_TRUE(loaded.ok()) << name << ": " << loaded.error().message;
    // A quad becomes two triangles, fanned from its first corner.
    EXPECT_EQ(loaded->polygons_triangulated, 1u) << name;
    EXPECT_EQ(loaded->mesh.triangles, (std::vector<std::uint32_t>{0, 1, 2, 0, 2, 3})) << name;
    EXPECT_EQ(loaded->input_topology.boundary_edges, 4u) << name;
  }
}

TEST(MeshIo, StlCornersAreWeldedAndReported) {
  const auto dir = test::scratch_dir("stl");
  write_file(dir / "sq.stl",
             "solid sq\n"
             "facet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 1 1 0\nendloop\nendfacet\n"
             "facet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 1 0\nvertex 0 1 0\nendloop\nendfacet\n"
             "endsolid sq\n");
  auto loaded = io::load_mesh(dir / "sq.stl");
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  EXPECT_EQ(loaded->mesh.vertex_count(), 4u);
  EXPECT_EQ(loaded->cleanup.welded_vertices, 2u);  // six corners, four distinct positions
  EXPECT_EQ(loaded->input_topology.boundary_edges, 4u);
}

// Each corrupt input must fail with a message naming the file and containing `expected`.
void expect_rejected(const fs::path& path, const std::string& expected) {
  auto loaded = io::load_mesh(path);
  ASSERT_FALSE(loaded.ok()) << path << " was accepted";
  EXPECT_NE(loaded.error().message.find(path.string()), std::string::npos) << loaded.error().message;
  EXPECT_NE(loaded.error().message.find(expected), std::string::npos) << loaded.error().message;
}

TEST(MeshIo, RejectsMissingEmptyDirectoryAndUnknownFiles) {
  const auto dir = test::scratch_dir("bad-files");
  expect_rejected(dir / "missing.ply", "no such file");
  write_file(dir / "empty.ply", "");
  expect_rejected(dir / "empty.ply", "empty file");
  fs::create_directory(dir / "folder.ply");
  expect_rejected(dir / "folder.ply", "directory");
  write_file(dir / "mesh.xyz", "1 2 3\n");
  expect_rejected(dir / "mesh.xyz", "unknown mesh format");
  write_file(dir / "junk.ply", std::string("garbage\0\x01\x02", 10));
  expect_rejected(dir / "junk.ply", "not a readable ply");
}

TEST(MeshIo, RejectsEveryTruncationOfABinaryPly) {
  const auto dir = test::scratch_dir("truncated");
  ASSERT_TRUE(io::save_mesh(dir / "full.ply", test::tetrahedron()).ok());
  const std::string bytes = read_file(dir / "full.ply");
  const std::size_t header_end = bytes.find("end_header\n") + 11;
  for (std::size_t length = header_end; length < bytes.size(); ++length) {
    write_file(dir / "cut.ply", bytes.substr(0, length));
    // Cuts inside the vertex records fail our size check against the header; cuts inside the
    // variable-length face lists fail in the reader. Both messages say "truncated".
    expect_rejected(dir / "cut.ply", "truncated");
  }
  // A header cut short has no vertices to offer.
  write_file(dir / "cut.ply", bytes.substr(0, header_end / 2));
  EXPECT_FALSE(io::load_mesh(dir / "cut.ply").ok());
}

TEST(MeshIo, RejectsFaceIndexOutOfRange) {
  const auto dir = test::scratch_dir("out-of-range");
  write_file(
      dir / "oob.ply",
      "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
      "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n");
  expect_rejected(dir / "oob.ply", "refers to vertex 7, but the file has 3 vertices");
  model::Mesh m = test::tetrahedron();
  m.triangles[5] = 4;
  ASSERT_TRUE(io::save_mesh(dir / "oob-binary.ply", m).ok());
  expect_rejected(dir / "oob-binary.ply", "refers to vertex 4");
  write_file(dir / "oob.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n");
  EXPECT_FALSE(io::load_mesh(dir / "oob.obj").ok());
}

TEST(MeshIo, RejectsNonFiniteCoordinates) {
  const auto dir = test::scratch_dir("nan");
  for (float bad : {std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::infinity()}) {
    model::Mesh m = test::tetrahedron();
    m.positions[7] = bad;  // vertex 2, y
    ASSERT_TRUE(io::save_mesh(dir / "bad.ply", m).ok());
    expect_rejected(dir / "bad.ply", "vertex 2 has a non-finite coordinate");
  }
}

TEST(MeshIo, RejectsMeshWithoutFaces) {
  const auto dir = test::scratch_dir("no-faces");
  write_file(dir / "points.ply",
             "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\n"
             "end_header\n0 0 0\n");
  expect_rejected(dir / "points.ply", "no faces");
}

TEST(MeshIo, WritingToAnUnknownExtensionOrMissingFolderFails) {
  EXPECT_FALSE(io::save_mesh("/nonexistent-folder/m.ply", test::square()).ok());
  EXPECT_FALSE(io::save_mesh(test::scratch_dir("ext") / "m.stl", test::square()).ok());
}

}  // namespace
}  // namespace mtlod::core::io
