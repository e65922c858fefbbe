// Streaming PLY: read and write meshes far larger than memory in chunks, element by element, without
// a whole-mesh reader. The out-of-core build reads its input through PlyReader and the generators
// write theirs through PlyWriter; load_mesh (OpenMesh) remains the reader of whole meshes.
//
// PlyReader takes ASCII, binary little- and big-endian PLY with any scalar property types (positions
// and normals converted to float, colours to 8 bits), skips properties and elements it does not use,
// and triangulates polygons as fans. It needs the vertex element before the face element, as every
// writer we know of puts them. ASCII values are read as whitespace-separated tokens, so a record may
// span lines. Memory is one 4 MiB read buffer plus the caller's spans, whatever the file's size.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <span>
#include <string>

#include "core/result.hpp"

namespace mtlod::core::io {

struct PlyHeader {
  std::uint64_t vertex_count = 0;
  std::uint64_t face_count = 0;  // polygons as the file counts them, before triangulation; 0 if none
  bool has_normals = false;      // nx, ny, nz
  bool has_colors = false;       // red, green, blue (or r, g, b / diffuse_*)
  bool binary = false;
  std::uint64_t header_bytes = 0;
};

class PlyReader {
 public:
  // Opens path and parses its header. Errors name the file and the problem: kNotFound (missing),
  // kCorrupt (not PLY, malformed header, no vertex element, counts the file is too small for, which
  // for a truncated binary file names the vertex it ends in), kUnsupported (format, version or type
  // unknown, no x/y/z or vertex_indices, faces before vertices), kLimitExceeded (over 2^32 - 1 vertices).
  static Result<PlyReader> open(const std::filesystem::path& path);

  PlyReader(PlyReader&&) noexcept;
  PlyReader& operator=(PlyReader&&) noexcept;
  ~PlyReader();

  const PlyHeader& header() const;

  // Reads the next vertices, at most positions.size() / 3 of them: x, y, z into positions and, when
  // the spans are not empty and the file has them, normals (3 per vertex) and colours (3 per vertex).
  // Returns how many were read: 0 once all vertices have been read (or passed over by
  // read_triangles). A file that ends early, a number that does not parse, or a non-finite x, y or z
  // (as load_mesh) is a kCorrupt error naming the vertex. After any error every call returns it again.
  Result<std::size_t> read_vertices(std::span<float> positions, std::span<float> normals = {},
                                    std::span<std::uint8_t> colors = {});

  // Reads the next faces as triangles (3 vertex ids each, fans for polygons) into triangles, whole
  // faces only, at most triangles.size() / 3 triangles (which must be at least the largest face's
  // triangle count, 253 for a uchar list). Skips the vertices not yet read. Returns how many
  // triangles were written: 0 once all faces have been read. Faces with fewer than 3 corners are
  // dropped; an index at or above the vertex count (or negative), or a file that ends early, is a
  // kCorrupt error naming the face, and a face with more triangles than the span holds is
  // kLimitExceeded. A face that fits the span but not what is left of it comes first in the next call.
  Result<std::size_t> read_triangles(std::span<std::uint32_t> triangles);

  // Faces read so far that had more than three corners, and faces dropped for having fewer.
  std::uint64_t polygons_triangulated() const;
  std::uint64_t faces_dropped() const;

 private:
  struct State;
  explicit PlyReader(std::unique_ptr<State> state);
  std::unique_ptr<State> state_;
};

// Writes binary little-endian PLY in chunks: the counts go in the header first, then every vertex,
// then every triangle (as "property list uchar uint vertex_indices"), the header and layout of
// save_mesh's PLY. Misuse (more than declared, triangles before all vertices, spans not matching the
// declared attributes) is kInvalidArgument; vertex ids are written unchecked. close() checks that the
// counts were met and reports any write failure (kIoError).
class PlyWriter {
 public:
  static Result<PlyWriter> create(const std::filesystem::path& path, std::uint64_t vertex_count,
                                  std::uint64_t triangle_count, bool normals, bool colors);

  PlyWriter(PlyWriter&&) noexcept;
  PlyWriter& operator=(PlyWriter&&) noexcept;
  ~PlyWriter();  // closes without reporting; call close() to learn of errors

  // positions (and normals / colours when the file has them) hold 3 values per vertex, the same
  // number of vertices in each span.
  Status write_vertices(std::span<const float> positions, std::span<const float> normals = {},
                        std::span<const std::uint8_t> colors = {});
  Status write_triangles(std::span<const std::uint32_t> triangles);
  Status close();

 private:
  struct State;
  explicit PlyWriter(std::unique_ptr<State> state);
  std::unique_ptr<State> state_;
};

}  // namespace mtlod::core::io
