// Streaming PLY: round trips through PlyWriter and PlyReader in chunk sizes that do not divide the
// counts, agreement with the whole-mesh reader (OpenMesh) on the shared scans, hand-written ASCII
// and big-endian files with everything the reader must skip or convert, and broken files that must
// come back as errors naming the file and the vertex or face.
#include "core/io/ply_stream.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "core/io/mesh_io.hpp"
#include "tests/core/test_meshes.hpp"

namespace mtlod::core::io {
namespace {

namespace fs = std::filesystem;

using test::read_file;
using test::write_file;

template <class T>
void put_le(std::string& out, T v) {
  char bytes[sizeof v];
  std::memcpy(bytes, &v, sizeof v);
  if constexpr (std::endian::native == std::endian::big) std::reverse(bytes, bytes + sizeof v);
  out.append(bytes, sizeof v);
}

template <class T>
void put_be(std::string& out, T v) {
  char bytes[sizeof v];
  std::memcpy(bytes, &v, sizeof v);
  if constexpr (std::endian::native == std::endian::little) std::reverse(bytes, bytes + sizeof v);
  out.append(bytes, sizeof v);
}

void expect_same_bits(const std::vector<float>& a, const std::vector<float>& b) {
  ASSERT_EQ(a.size(), b.size());
  if (a.empty()) return;
  EXPECT_EQ(std::memcmp(a.data(), b.data(), a.size() * sizeof(float)), 0);
}

struct Streamed {
  std::vector<float> positions;
  std::vector<float> normals;
  std::vector<std::uint8_t> colors;
  std::vector<std::uint32_t> triangles;
};

// Reads everything reader has left, vertex_chunk vertices and room for triangle_chunk triangles at
// a time; normals and colours only when the file has them.
Result<Streamed> stream_rest(io::PlyReader& reader, std::size_t vertex_chunk, std::size_t triangle_chunk) {
  Streamed out;
  std::vector<float> p(3 * vertex_chunk), n(3 * vertex_chunk);
  std::vector<std::uint8_t> c(3 * vertex_chunk);
  for (;;) {
    MTLOD_TRY(const std::size_t got, reader.read_vertices(p, n, c));
    if (got == 0) break;
    out.positions.insert(out.positions.end(), p.begin(), p.begin() + 3 * got);
    if (reader.header().has_normals) out.normals.insert(out.normals.end(), n.begin(), n.begin() + 3 * got);
    if (reader.header().has_colors) out.colors.insert(out.colors.end(), c.begin(), c.begin() + 3 * got);
  }
  std::vector<std::uint32_t> t(3 * triangle_chunk);
  for (;;) {
    MTLOD_TRY(const std::size_t got, reader.read_triangles(t));
    if (got == 0) break;
    out.triangles.insert(out.triangles.end(), t.begin(), t.begin() + 3 * got);
  }
  return out;
}

Result<Streamed> stream_file(const fs::path& path, std::size_t vertex_chunk = 1000,
                             std::size_t triangle_chunk = 1000) {
  MTLOD_TRY(io::PlyReader reader, io::PlyReader::open(path));
  return stream_rest(reader, vertex_chunk, triangle_chunk);
}

// The first error of opening and reading the whole file, or "" when it reads.
Error read_error(const fs::path& path) {
  auto streamed = stream_file(path);
  if (streamed.ok()) return Error{ErrorCode::kInternal, ""};
  return streamed.error();
}

void expect_error(const fs::path& path, ErrorCode code, const std::string& words) {
  const Error error = read_error(path);
  EXPECT_EQ(error.code, code) << path << ": " << error.message;
  EXPECT_NE(error.message.find(words), std::string::npos) << error.message;
  EXPECT_NE(error.message.find(path.string()), std::string::npos) << error.message;
}

// A fixed-seed mesh with awkward floats and indices anywhere in range.
model::Mesh random_mesh(std::size_t vertices, std::size_t triangles, bool normals, bool colors) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> coordinate(-1e3f, 1e3f);
  std::uniform_int_distribution<std::uint32_t> vertex(0, static_cast<std::uint32_t>(vertices - 1));
  std::uniform_int_distribution<int> byte(0, 255);
  model::Mesh m;
  for (std::size_t i = 0; i < 3 * vertices; ++i) m.positions.push_back(coordinate(rng));
  m.positions[0] = -0.0f;
  m.positions[1] = 1e-40f;  // subnormal
  for (std::size_t i = 0; i < 3 * triangles; ++i) m.triangles.push_back(vertex(rng));
  if (normals) {
    for (std::size_t i = 0; i < 3 * vertices; ++i) m.normals.push_back(coordinate(rng) / 1e3f);
  }
  if (colors) {
    for (std::size_t i = 0; i < 3 * vertices; ++i) m.colors.push_back(static_cast<std::uint8_t>(byte(rng)));
  }
  return m;
}

// Writes m through PlyWriter in chunks of the given sizes.
Status write_in_chunks(const fs::path& path, const model::Mesh& m, std::size_t vertex_chunk,
                       std::size_t triangle_chunk) {
  MTLOD_TRY(io::PlyWriter writer, io::PlyWriter::create(path, m.vertex_count(), m.triangle_count(),
                                                        m.has_normals(), m.has_colors()));
  for (std::size_t v = 0; v < m.vertex_count(); v += vertex_chunk) {
    const std::size_t n = std::min(vertex_chunk, m.vertex_count() - v);
    const auto part = [&](const auto& values) {
      return values.empty() ? std::span(values.data(), 0) : std::span(values).subspan(3 * v, 3 * n);
    };
    MTLOD_RETURN_IF_ERROR(writer.write_vertices(part(m.positions), part(m.normals), part(m.colors)));
  }
  for (std::size_t t = 0; t < m.triangle_count(); t += triangle_chunk) {
    const std::size_t n = std::min(triangle_chunk, m.triangle_count() - t);
    MTLOD_RETURN_IF_ERROR(writer.write_triangles(std::span(m.triangles).subspan(3 * t, 3 * n)));
  }
  return writer.close();
}

TEST(PlyStream, RoundTripsInChunksThatDoNotDivideTheCounts) {
  const auto dir = test::scratch_dir("ply-stream-roundtrip");
  for (const bool normals : {false, true}) {
    for (const bool colors : {false, true}) {
      SCOPED_TRACE(testing::Message() << "normals " << normals << ", colours " << colors);
      const model::Mesh m = random_mesh(1000, 1999, normals, colors);
      ASSERT_TRUE(write_in_chunks(dir / "m.ply", m, 7, 11).ok());
      auto reader = io::PlyReader::open(dir / "m.ply");
      ASSERT_TRUE(reader.ok()) << reader.error().message;
      EXPECT_EQ(reader->header().vertex_count, 1000u);
      EXPECT_EQ(reader->header().face_count, 1999u);
      EXPECT_EQ(reader->header().has_normals, normals);
      EXPECT_EQ(reader->header().has_colors, colors);
      EXPECT_TRUE(reader->header().binary);
      auto read = stream_rest(*reader, 13, 5);
      ASSERT_TRUE(read.ok()) << read.error().message;
      expect_same_bits(read->positions, m.positions);
      expect_same_bits(read->normals, m.normals);
      EXPECT_EQ(read->colors, m.colors);
      EXPECT_EQ(read->triangles, m.triangles);
      EXPECT_EQ(reader->polygons_triangulated(), 0u);
      EXPECT_EQ(reader->faces_dropped(), 0u);
    }
  }
}

TEST(PlyStream, ReadingTrianglesFirstSkipsTheVertices) {
  // A million vertices of 12 bytes are three times the reader's buffer: the skip seeks past them.
  const auto dir = test::scratch_dir("ply-stream-skip");
  const model::Mesh m = random_mesh(1000000, 5000, false, false);
  ASSERT_TRUE(io::save_mesh(dir / "m.ply", m).ok());
  auto reader = io::PlyReader::open(dir / "m.ply");
  ASSERT_TRUE(reader.ok()) << reader.error().message;
  std::vector<std::uint32_t> triangles(3 * 10000);
  auto got = reader->read_triangles(triangles);
  ASSERT_TRUE(got.ok()) << got.error().message;
  ASSERT_EQ(*got, 5000u);
  triangles.resize(3 * 5000);
  EXPECT_EQ(triangles, m.triangles);
  std::vector<float> positions(30);
  auto vertices = reader->read_vertices(positions);
  ASSERT_TRUE(vertices.ok());
  EXPECT_EQ(*vertices, 0u);  // the vertices were passed over
}

TEST(PlyStream, AgreesWithLoadMeshOnTheSharedScans) {
  const fs::path dir = test::shared_meshes_dir();
  if (!fs::exists(dir / "bunny-zipper-69k.ply")) GTEST_SKIP() << "no shared meshes at " << dir;
  int files = 0;
  for (const auto& entry : fs::directory_iterator(dir)) {
    if (entry.path().extension() != ".ply") continue;
    SCOPED_TRACE(entry.path().string());
    ++files;
    auto expected = io::load_mesh(entry.path(), {.clean = false});
    ASSERT_TRUE(expected.ok()) << expected.error().message;
    auto reader = io::PlyReader::open(entry.path());
    ASSERT_TRUE(reader.ok()) << reader.error().message;
    EXPECT_EQ(reader->header().vertex_count, expected->mesh.vertex_count());
    auto read = stream_rest(*reader, 4099, 3001);
    ASSERT_TRUE(read.ok()) << read.error().message;
    expect_same_bits(read->positions, expected->mesh.positions);
    EXPECT_EQ(read->triangles, expected->mesh.triangles);
    expect_same_bits(read->normals, expected->mesh.normals);
    EXPECT_EQ(read->colors, expected->mesh.colors);
    EXPECT_EQ(reader->polygons_triangulated(), expected->polygons_triangulated);
  }
  EXPECT_GE(files, 8);
}

TEST(PlyStream, AgreesWithLoadMeshOnTheAsciiModels) {
  // scripts/prepare-models.sh writes the built-in bunny and dragon as ASCII PLY.
  int files = 0;
  for (const char* name : {"bunny.ply", "dragon-871k.ply"}) {
    const fs::path path = test::models_dir() / name;
    if (!fs::exists(path)) continue;
    SCOPED_TRACE(path.string());
    ++files;
    auto expected = io::load_mesh(path, {.clean = false});
    ASSERT_TRUE(expected.ok()) << expected.error().message;
    auto read = stream_file(path, 777, 999);
    ASSERT_TRUE(read.ok()) << read.error().message;
    expect_same_bits(read->positions, expected->mesh.positions);
    EXPECT_EQ(read->triangles, expected->mesh.triangles);
  }
  if (files == 0) GTEST_SKIP() << "no built-in models in " << test::models_dir();
}

// The mesh both hand-written files below hold: 7 vertices; faces a triangle, a quad, a 2-corner
// face, a 5-gon and a triangle. Polygons are fans from their first corner, the 2-corner face is dropped.
const std::vector<float> kHandPositions = {0, 0, 0, 1,    0, 0, 1,      1,    0, 0,   1,
                                           0, 2, 0, 0.5f, 2, 1, -0.25f, 1.5f, 2, 1000};
const std::vector<float> kHandNormals = {0, 0, 1, 0, 0, 1, 0, 0,    1,     0,    0,
                                         1, 0, 0, 1, 0, 0, 1, 0.5f, -0.5f, 0.75f};
const std::vector<std::uint32_t> kHandTriangles = {0, 1, 2,                    // triangle
                                                   0, 1, 2, 0, 2, 3,           // quad 0 1 2 3
                                                   1, 4, 5, 1, 5, 6, 1, 6, 2,  // 5-gon 1 4 5 6 2
                                                   3, 2, 6};

// ASCII with a CRLF header, comments, elements before, between and after, extra vertex properties
// (one between y and x), extra face properties before and after the index list, odd spacing.
const std::string kHandAscii =
    "ply\r\n"
    "format ascii 1.0\r\n"
    "comment written by hand\r\n"
    "obj_info made for the streaming reader's test\r\n"
    "element material 2\r\n"
    "property list uchar float ambient\r\n"
    "property uchar id\r\n"
    "element vertex 7\r\n"
    "property double x\r\n"
    "property float confidence\r\n"
    "property float y\r\n"
    "property float z\r\n"
    "property float nx\r\n"
    "property float ny\r\n"
    "property float nz\r\n"
    "property uchar red\r\n"
    "property uchar green\r\n"
    "property uchar blue\r\n"
    "property uchar alpha\r\n"
    "element edge 2\r\n"
    "property int vertex1\r\n"
    "property int vertex2\r\n"
    "element face 5\r\n"
    "property uchar flags\r\n"
    "property list uchar int vertex_indices\r\n"
    "property list uchar float texcoord\r\n"
    "element trailer 1\r\n"
    "property float whatever\r\n"
    "end_header\r\n"
    "3 0.1 0.2 0.3 7\n"
    "0 1\n"
    "0 0.9 0 0 0 0 1 255 0 0 255\n"
    "1 0.9 0 0 0 0 1 0 255 0 255\n"
    "1\t0.9\t1\t0\t0\t0\t1\t0\t0\t255\t255\n"
    "0 0.9 1 0   0 0 1   10 20 30 255\n"
    "2 0.9 0 0.5 0 0 1 1 2 3 255\n"
    "+2 0.9 1 -0.25 0 0 1 200 100 50 255\n"
    "1.5 0.9 2 1e3 0.5 -0.5 0.75\n7 8 9 255\n"
    "0 1\n"
    "1 2\n"
    "0 3 0 1 2 6 0 0 1 0 0 1\n"
    "1 4 0 1 2 3 0\n"
    "0 2 4 5 0\n"
    "2 5 1 4 5 6 2 2 0.5 0.5\n"
    "0 3 3 2 6 0\n"
    "1.0\n";
const std::vector<std::uint8_t> kHandAsciiColors = {255, 0, 0, 0, 255, 0,   0,  0, 255, 10, 20,
                                                    30,  1, 2, 3, 200, 100, 50, 7, 8,   9};

TEST(PlyStream, ReadsAHandWrittenAsciiFile) {
  const auto dir = test::scratch_dir("ply-stream-ascii");
  write_file(dir / "hand.ply", kHandAscii);
  auto reader = io::PlyReader::open(dir / "hand.ply");
  ASSERT_TRUE(reader.ok()) << reader.error().message;
  EXPECT_FALSE(reader->header().binary);
  EXPECT_EQ(reader->header().vertex_count, 7u);
  EXPECT_EQ(reader->header().face_count, 5u);
  EXPECT_TRUE(reader->header().has_normals);
  EXPECT_TRUE(reader->header().has_colors);
  auto read = stream_rest(*reader, 3, 3);
  ASSERT_TRUE(read.ok()) << read.error().message;
  EXPECT_EQ(read->positions, kHandPositions);
  EXPECT_EQ(read->normals, kHandNormals);
  EXPECT_EQ(read->colors, kHandAsciiColors);
  EXPECT_EQ(read->triangles, kHandTriangles);
  EXPECT_EQ(reader->polygons_triangulated(), 2u);
  EXPECT_EQ(reader->faces_dropped(), 1u);

  // Triangles first: the material, vertex and edge records are skipped token by token.
  auto triangles_only = io::PlyReader::open(dir / "hand.ply");
  ASSERT_TRUE(triangles_only.ok());
  std::vector<std::uint32_t> room(3 * 253);
  auto got = triangles_only->read_triangles(room);
  ASSERT_TRUE(got.ok()) << got.error().message;
  room.resize(3 * *got);
  EXPECT_EQ(room, kHandTriangles);
}

// The same mesh in big-endian binary with other type names, a list inside the vertex element,
// colours as float, double and ushort, and faces as "list int32 uint16 vertex_index".
std::string hand_big_endian() {
  std::string out =
      "ply\r\n"
      "format binary_big_endian 1.0\r\n"
      "comment big-endian, sized type names\r\n"
      "element vertex 7\r\n"
      "property float32 x\r\n"
      "property float32 y\r\n"
      "property int8 flag\r\n"
      "property float32 z\r\n"
      "property float64 nx\r\n"
      "property float64 ny\r\n"
      "property float64 nz\r\n"
      "property list uint8 uint16 neighbours\r\n"
      "property float32 r\r\n"
      "property float64 g\r\n"
      "property uint16 b\r\n"
      "element edge 1\r\n"
      "property list uchar int vertices\r\n"
      "element face 5\r\n"
      "property list int32 uint16 vertex_index\r\n"
      "property int16 material\r\n"
      "end_header\r\n";
  const float red[7] = {1, 0, 0, 0.5f, 0.25f, 2, -1};
  const double green[7] = {0, 1, 0, 0.1, 0.5, 1, 0};
  const std::uint16_t blue[7] = {0, 0, 255, 300, 3, 1000, 9};
  for (int v = 0; v < 7; ++v) {
    put_be(out, kHandPositions[3 * v]);
    put_be(out, kHandPositions[3 * v + 1]);
    put_be(out, std::int8_t{-5});
    put_be(out, kHandPositions[3 * v + 2]);
    for (int c = 0; c < 3; ++c) put_be(out, static_cast<double>(kHandNormals[3 * v + c]));
    put_be(out, static_cast<std::uint8_t>(v % 3));  // a list of v % 3 neighbours
    for (int k = 0; k < v % 3; ++k) put_be(out, static_cast<std::uint16_t>(k));
    put_be(out, red[v]);
    put_be(out, green[v]);
    put_be(out, blue[v]);
  }
  put_be(out, std::uint8_t{2});
  put_be(out, std::int32_t{0});
  put_be(out, std::int32_t{1});
  const std::vector<std::vector<std::uint16_t>> faces = {
      {0, 1, 2}, {0, 1, 2, 3}, {4, 5}, {1, 4, 5, 6, 2}, {3, 2, 6}};
  for (const auto& face : faces) {
    put_be(out, static_cast<std::int32_t>(face.size()));
    for (std::uint16_t v : face) put_be(out, v);
    put_be(out, std::int16_t{-300});
  }
  return out;
}

TEST(PlyStream, ReadsAHandWrittenBigEndianFile) {
  const auto dir = test::scratch_dir("ply-stream-big-endian");
  write_file(dir / "hand.ply", hand_big_endian());
  auto reader = io::PlyReader::open(dir / "hand.ply");
  ASSERT_TRUE(reader.ok()) << reader.error().message;
  EXPECT_TRUE(reader->header().binary);
  EXPECT_TRUE(reader->header().has_normals);
  EXPECT_TRUE(reader->header().has_colors);
  auto read = stream_rest(*reader, 2, 4);
  ASSERT_TRUE(read.ok()) << read.error().message;
  EXPECT_EQ(read->positions, kHandPositions);
  EXPECT_EQ(read->normals, kHandNormals);
  // Float channels scale [0, 1] to 0..255 and clamp (0.5 -> 127.5 rounds to 128, 0.25 -> 63.75 to
  // 64, 0.1 -> 25.5 to 26, 2 -> 255, -1 -> 0); the ushort channel clamps (300, 1000 -> 255).
  const std::vector<std::uint8_t> colors = {255, 0,  0,   0, 255, 0,   0,   0, 255, 128, 26,
                                            255, 64, 128, 3, 255, 255, 255, 0, 0,   9};
  EXPECT_EQ(read->colors, colors);
  EXPECT_EQ(read->triangles, kHandTriangles);
  EXPECT_EQ(reader->polygons_triangulated(), 2u);
  EXPECT_EQ(reader->faces_dropped(), 1u);
}

TEST(PlyStream, PolygonsWaitForRoomAndTooLittleRoomIsAnError) {
  const auto dir = test::scratch_dir("ply-stream-room");
  write_file(dir / "hand.ply", kHandAscii);
  // Room for 4 triangles: the triangle and the quad take 3, the 5-gon's 3 wait for the next call.
  auto reader = io::PlyReader::open(dir / "hand.ply");
  ASSERT_TRUE(reader.ok());
  std::vector<std::uint32_t> room(12), all;
  std::vector<std::size_t> counts;
  for (;;) {
    auto got = reader->read_triangles(room);
    ASSERT_TRUE(got.ok()) << got.error().message;
    if (*got == 0) break;
    counts.push_back(*got);
    all.insert(all.end(), room.begin(), room.begin() + 3 * *got);
  }
  EXPECT_EQ(counts, (std::vector<std::size_t>{3, 4}));
  EXPECT_EQ(all, kHandTriangles);
  // Room for 2: the quad waits once; the 5-gon's 3 triangles never fit.
  auto small = io::PlyReader::open(dir / "hand.ply");
  ASSERT_TRUE(small.ok());
  room.resize(6);
  counts.clear();
  Result<std::size_t> got = std::size_t{0};
  while ((got = small->read_triangles(room)).ok() && *got > 0) counts.push_back(*got);
  EXPECT_EQ(counts, (std::vector<std::size_t>{1, 2}));
  ASSERT_FALSE(got.ok());
  EXPECT_EQ(got.error().code, ErrorCode::kLimitExceeded);
  EXPECT_NE(got.error().message.find("face 3 has 5 corners"), std::string::npos) << got.error().message;
  // The error stays, whatever the room.
  std::vector<std::uint32_t> large(3 * 253);
  EXPECT_FALSE(small->read_triangles(large).ok());
}

TEST(PlyStream, TruncatedBinaryFilesNameTheVertexOrFace) {
  const auto dir = test::scratch_dir("ply-stream-truncated");
  model::Mesh m = test::tetrahedron();
  m.normals.assign(12, 0.5f);
  ASSERT_TRUE(io::save_mesh(dir / "full.ply", m).ok());
  const std::string bytes = read_file(dir / "full.ply");
  const std::size_t header = bytes.find("end_header\n") + 11;
  // 4 vertices of 24 bytes, then 4 faces of 13 (a length byte and 3 uint32).
  ASSERT_EQ(bytes.size(), header + 4 * 24 + 4 * 13);
  const std::pair<std::size_t, std::string> cuts[] = {
      {header + 5, "vertex 0"},
      {header + 2 * 24 + 10, "vertex 2"},
      {header + 4 * 24 - 1, "vertex 3"},
      {header + 4 * 24, "face"},  // no room even for the 4 length bytes: found at open
      {header + 4 * 24 + 7, "face 0"},
      {header + 4 * 24 + 2 * 13 + 5, "face 2"},
      {bytes.size() - 1, "face 3"},
  };
  for (const auto& [length, words] : cuts) {
    SCOPED_TRACE(length);
    write_file(dir / "cut.ply", bytes.substr(0, length));
    expect_error(dir / "cut.ply", ErrorCode::kCorrupt, words);
  }
  // Every other cut fails too, without a crash.
  for (std::size_t length = 0; length < bytes.size(); ++length) {
    write_file(dir / "cut.ply", bytes.substr(0, length));
    EXPECT_NE(read_error(dir / "cut.ply").message, "") << length;
  }
}

TEST(PlyStream, TruncatedAsciiFileNamesTheVertexOrFace) {
  const auto dir = test::scratch_dir("ply-stream-truncated-ascii");
  const std::string text =
      "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
      "element face 1\nproperty list uchar int vertex_indices\nend_header\n"
      "0.500000 0.250000 0.125000\n1.500000 1.250000 1.125000\n2.500000 2.250000 2.125000\n3 0 1 2\n";
  write_file(dir / "cut.ply", text.substr(0, text.find("1.250000") + 4));
  expect_error(dir / "cut.ply", ErrorCode::kCorrupt, "vertex 1");
  write_file(dir / "cut.ply", text.substr(0, text.size() - 3));
  expect_error(dir / "cut.ply", ErrorCode::kCorrupt, "face 0");
  write_file(dir / "bad.ply",
             text.substr(0, text.find("2.250000")) + "2.2x0000" + text.substr(text.find(" 2.125")));
  expect_error(dir / "bad.ply", ErrorCode::kCorrupt, "vertex 2: '2.2x0000' is not a valid float value");
}

TEST(PlyStream, IndexOutOfRangeNamesTheFace) {
  const auto dir = test::scratch_dir("ply-stream-index");
  model::Mesh m = test::tetrahedron();
  m.triangles[5] = 4;  // face 1
  ASSERT_TRUE(io::save_mesh(dir / "oob.ply", m).ok());
  expect_error(dir / "oob.ply", ErrorCode::kCorrupt,
               "face 1 refers to vertex 4, but the file has 4 vertices");
  // A negative int32 index, in the layout the copy-only loop takes.
  std::string negative =
      "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
      "property float z\nelement face 2\nproperty list uchar int vertex_indices\nend_header\n";
  for (int i = 0; i < 9; ++i) put_le(negative, static_cast<float>(i));
  for (const std::int32_t last : {2, -1}) {
    put_le(negative, std::uint8_t{3});
    put_le(negative, std::int32_t{0});
    put_le(negative, std::int32_t{1});
    put_le(negative, last);
  }
  write_file(dir / "negative.ply", negative);
  expect_error(dir / "negative.ply", ErrorCode::kCorrupt, "face 1 refers to vertex -1");
  write_file(
      dir / "out-of-range.ply",
      "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
      "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n");
  expect_error(dir / "out-of-range.ply", ErrorCode::kCorrupt,
               "face 0 refers to vertex 7, but the file has 3");
}

TEST(PlyStream, NonFiniteCoordinateNamesTheVertex) {
  const auto dir = test::scratch_dir("ply-stream-nan");
  model::Mesh m = test::tetrahedron();
  m.positions[7] = std::numeric_limits<float>::quiet_NaN();  // vertex 2, y
  ASSERT_TRUE(io::save_mesh(dir / "nan.ply", m).ok());
  expect_error(dir / "nan.ply", ErrorCode::kCorrupt, "vertex 2 has a non-finite coordinate");
}

TEST(PlyStream, RejectsBadHeaders) {
  const auto dir = test::scratch_dir("ply-stream-headers");
  const std::string xyz = "property float x\nproperty float y\nproperty float z\n";
  const std::string face = "element face 1\nproperty list uchar int vertex_indices\n";
  const std::string le = "ply\nformat binary_little_endian 1.0\n";
  const std::string ascii = "ply\nformat ascii 1.0\n";
  struct Case {
    std::string name;
    std::string bytes;
    ErrorCode code;
    std::string words;
  };
  const Case cases[] = {
      {"not-ply", std::string("garbage\0\x01\x02", 10), ErrorCode::kCorrupt, "not a PLY file"},
      {"empty", "", ErrorCode::kCorrupt, "empty file"},
      {"no-end", ascii + "element vertex 1\n" + xyz, ErrorCode::kCorrupt, "no end_header"},
      {"faces-first",
       ascii + face + "element vertex 3\n" + xyz + "end_header\n3 0 1 2\n0 0 0\n1 0 0\n0 1 0\n",
       ErrorCode::kUnsupported, "face element comes before the vertex element"},
      {"no-x", ascii + "element vertex 1\nproperty float y\nproperty float z\nend_header\n0 0\n",
       ErrorCode::kUnsupported, "no 'x' property"},
      {"no-vertex", ascii + "element point 1\n" + xyz + "end_header\n0 0 0\n", ErrorCode::kCorrupt,
       "no vertex element"},
      {"no-indices",
       ascii + "element vertex 1\n" + xyz + "element face 1\nproperty list uchar int corners\n" +
           "end_header\n0 0 0\n3 0 0 0\n",
       ErrorCode::kUnsupported, "no 'vertex_indices' list"},
      {"format", "ply\nformat binary_middle_endian 1.0\nelement vertex 0\n" + xyz + "end_header\n",
       ErrorCode::kUnsupported, "unknown format"},
      {"version", "ply\nformat ascii 2.0\nelement vertex 0\n" + xyz + "end_header\n", ErrorCode::kUnsupported,
       "unknown PLY version"},
      {"type", ascii + "element vertex 0\nproperty float x\nproperty quad y\nproperty float z\nend_header\n",
       ErrorCode::kUnsupported, "unknown property type"},
      {"float-length",
       ascii + "element vertex 0\n" + xyz +
           "element face 0\nproperty list float int vertex_indices\nend_header\n",
       ErrorCode::kUnsupported, "list length that is not an integer"},
      {"huge-vertices", le + "element vertex 18446744073709551615\n" + xyz + "end_header\n",
       ErrorCode::kCorrupt, "truncated or impossible count"},
      {"huge-faces",
       le + "element vertex 0\n" + xyz + "element face 4000000000\n" +
           "property list uchar int vertex_indices\nend_header\n",
       ErrorCode::kCorrupt, "too short for 4000000000 face records"},
      {"huge-ascii", ascii + "element vertex 1000000000000\n" + xyz + "end_header\n0 0 0\n",
       ErrorCode::kCorrupt, "truncated or impossible count"},
      {"count-overflow", ascii + "element vertex 99999999999999999999999\n" + xyz + "end_header\n",
       ErrorCode::kCorrupt, "bad element count"},
      {"negative-count", ascii + "element vertex -1\n" + xyz + "end_header\n", ErrorCode::kCorrupt,
       "bad element count"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    write_file(dir / (c.name + ".ply"), c.bytes);
    expect_error(dir / (c.name + ".ply"), c.code, c.words);
  }
  expect_error(dir / "missing.ply", ErrorCode::kNotFound, "no such file");
  fs::create_directory(dir / "folder.ply");
  expect_error(dir / "folder.ply", ErrorCode::kInvalidArgument, "directory");
}

TEST(PlyStream, LyingListLengthsAreErrorsNotAllocations) {
  const auto dir = test::scratch_dir("ply-stream-lists");
  const std::string head =
      "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
      "property float z\nelement face 1\n";
  std::string vertices;
  for (int i = 0; i < 9; ++i) put_le(vertices, static_cast<float>(i));
  // A skipped list that claims 4e9 floats, far beyond the file's end.
  std::string skipped =
      head + "property list uint float junk\nproperty list uchar int vertex_indices\nend_header\n" + vertices;
  put_le(skipped, std::uint32_t{4000000000u});
  write_file(dir / "skipped.ply", skipped + std::string(20, '\0'));
  expect_error(dir / "skipped.ply", ErrorCode::kCorrupt, "ends inside face 0");
  // An index list that claims 4e9 corners: more triangles than any room.
  std::string indices = head + "property list uint int vertex_indices\nend_header\n" + vertices;
  put_le(indices, std::uint32_t{4000000000u});
  write_file(dir / "indices.ply", indices + std::string(20, '\0'));
  expect_error(dir / "indices.ply", ErrorCode::kLimitExceeded, "face 0 has 4000000000 corners");
}

TEST(PlyWriter, RejectsMisuse) {
  const auto dir = test::scratch_dir("ply-writer-misuse");
  const std::vector<float> three = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  const std::vector<std::uint32_t> one = {0, 1, 2};
  {
    auto writer = io::PlyWriter::create(dir / "a.ply", 2, 1, false, false);
    ASSERT_TRUE(writer.ok());
    EXPECT_EQ(writer->write_triangles(one).error().code, ErrorCode::kInvalidArgument);  // before the vertices
    EXPECT_EQ(writer->write_vertices(three).error().code, ErrorCode::kInvalidArgument);  // 3 > 2 declared
    EXPECT_EQ(writer->write_vertices(std::span(three).first(6), std::span(three).first(6)).error().code,
              ErrorCode::kInvalidArgument);  // normals the header does not declare
    EXPECT_EQ(writer->write_vertices(std::span(three).first(4)).error().code, ErrorCode::kInvalidArgument);
    ASSERT_TRUE(writer->write_vertices(std::span(three).first(6)).ok());
    const Status closed = writer->close();
    ASSERT_FALSE(closed.ok());
    EXPECT_EQ(closed.error().code, ErrorCode::kInvalidArgument);
    EXPECT_NE(closed.error().message.find("closed after 2 of 2 vertices and 0 of 1 triangles"),
              std::string::npos)
        << closed.error().message;
    EXPECT_EQ(writer->write_triangles(one).error().code, ErrorCode::kInvalidArgument);  // after close
  }
  {
    auto writer = io::PlyWriter::create(dir / "b.ply", 3, 1, false, false);
    ASSERT_TRUE(writer.ok());
    ASSERT_TRUE(writer->write_vertices(three).ok());
    ASSERT_TRUE(writer->write_triangles(one).ok());
    EXPECT_EQ(writer->write_triangles(one).error().code, ErrorCode::kInvalidArgument);  // 2 > 1 declared
    EXPECT_TRUE(writer->close().ok());
  }
  auto missing = io::PlyWriter::create("/nonexistent-folder/m.ply", 3, 1, false, false);
  ASSERT_FALSE(missing.ok());
  EXPECT_EQ(missing.error().code, ErrorCode::kIoError);
}

TEST(PlyWriter, CloseReportsAFailedWrite) {
  if (!fs::exists("/dev/full")) GTEST_SKIP() << "no /dev/full";
  // /dev/full accepts the open and fails every write with ENOSPC.
  auto writer = io::PlyWriter::create("/dev/full", 3, 1, false, false);
  ASSERT_TRUE(writer.ok()) << writer.error().message;
  const std::vector<float> three = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  ASSERT_TRUE(writer->write_vertices(three).ok());  // still in the writer's buffer
  ASSERT_TRUE(writer->write_triangles(std::vector<std::uint32_t>{0, 1, 2}).ok());
  const Status closed = writer->close();
  ASSERT_FALSE(closed.ok());
  EXPECT_EQ(closed.error().code, ErrorCode::kIoError);
  EXPECT_EQ(closed.error().message, "/dev/full: write failed");
}

TEST(PlyWriter, SaveMeshWritesTheDocumentedBytes) {
  // The header and records spelled out: little-endian float x y z, float nx ny nz, uchar colour,
  // then faces as a length byte 3 and three uint32.
  const auto dir = test::scratch_dir("ply-writer-bytes");
  model::Mesh m = test::tetrahedron();
  for (int i = 0; i < 12; ++i) m.normals.push_back(static_cast<float>(i) / 8.0f);
  for (int i = 0; i < 12; ++i) m.colors.push_back(static_cast<std::uint8_t>(20 * i));
  for (const bool attributes : {false, true}) {
    model::Mesh written = m;
    if (!attributes) {
      written.normals.clear();
      written.colors.clear();
    }
    std::string expected =
        "ply\nformat binary_little_endian 1.0\ncomment written by mtlod\nelement vertex 4\n"
        "property float x\nproperty float y\nproperty float z\n";
    if (attributes) {
      expected +=
          "property float nx\nproperty float ny\nproperty float nz\n"
          "property uchar red\nproperty uchar green\nproperty uchar blue\n";
    }
    expected += "element face 4\nproperty list uchar uint vertex_indices\nend_header\n";
    for (int v = 0; v < 4; ++v) {
      for (int c = 0; c < 3; ++c) put_le(expected, m.positions[3 * v + c]);
      if (!attributes) continue;
      for (int c = 0; c < 3; ++c) put_le(expected, m.normals[3 * v + c]);
      for (int c = 0; c < 3; ++c) put_le(expected, m.colors[3 * v + c]);
    }
    for (int t = 0; t < 4; ++t) {
      put_le(expected, std::uint8_t{3});
      for (int c = 0; c < 3; ++c) put_le(expected, m.triangles[3 * t + c]);
    }
    ASSERT_TRUE(io::save_mesh(dir / "m.ply", written).ok());
    EXPECT_EQ(read_file(dir / "m.ply"), expected) << "attributes " << attributes;
  }
}

}  // namespace
}  // namespace mtlod::core::io
