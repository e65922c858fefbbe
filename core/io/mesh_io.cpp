// Reading meshes through OpenMesh's IOManager into flat arrays, and writing binary PLY and OBJ.
// OpenMesh's own TriMesh would drop or split non-manifold faces (real scans have them, see the
// shared meshes' README), so a BaseImporter of ours receives the reader's vertices and faces as
// they are and keeps them in Mesh's struct-of-arrays.
#include "core/io/mesh_io.hpp"

#include <OpenMesh/Core/IO/IOManager.hh>
#include <OpenMesh/Core/IO/importer/BaseImporter.hh>
#include <OpenMesh/Core/System/omstream.hh>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <span>
#include <string>
#include <system_error>

#include "core/io/ply_stream.hpp"
#include "fmt/format.h"

namespace mtlod::core::io {
namespace {

namespace OM = OpenMesh;

// Receives what an OpenMesh reader parses. Only vertices, vertex normals, vertex colours and faces
// matter; everything else (texture coordinates, face colours, halfedge data) is ignored.
class FlatImporter final : public OM::IO::BaseImporter {
 public:
  model::Mesh mesh;
  std::size_t polygons_triangulated = 0;
  std::string first_error;  // the importer cannot return errors through OpenMesh: remember the first
  bool saw_normal = false;
  bool saw_color = false;

  OM::VertexHandle add_vertex(const OM::Vec3f& p) override {
    const std::size_t id = mesh.positions.size() / 3;
    mesh.positions.insert(mesh.positions.end(), {p[0], p[1], p[2]});
    return OM::VertexHandle(static_cast<int>(id));
  }
  OM::VertexHandle add_vertex() override { return add_vertex(OM::Vec3f(0, 0, 0)); }

  OM::FaceHandle add_face(const VHandles& corners) override {
    const std::size_t face = faces_++;
    if (corners.size() < 3) {
      note(fmt::format("face {} has {} corners", face, corners.size()));
      return OM::FaceHandle();
    }
    const std::size_t n = mesh.positions.size() / 3;
    for (const OM::VertexHandle& vh : corners) {
      if (vh.idx() < 0 || static_cast<std::size_t>(vh.idx()) >= n) {
        note(fmt::format("face {} refers to vertex {}, but the file has {} vertices", face, vh.idx(), n));
        return OM::FaceHandle();
      }
    }
    // Polygons become a fan from their first corner; readers hand over convex polygons in practice.
    if (corners.size() > 3) ++polygons_triangulated;
    for (std::size_t k = 1; k + 1 < corners.size(); ++k) {
      mesh.triangles.insert(mesh.triangles.end(), {static_cast<std::uint32_t>(corners[0].idx()),
                                                   static_cast<std::uint32_t>(corners[k].idx()),
                                                   static_cast<std::uint32_t>(corners[k + 1].idx())});
    }
    return OM::FaceHandle(static_cast<int>(face));
  }

  void set_point(OM::VertexHandle vh, const OM::Vec3f& p) override {
    if (!valid(vh)) return;
    std::copy_n(p.data(), 3, &mesh.positions[3 * static_cast<std::size_t>(vh.idx())]);
  }
  void set_normal(OM::VertexHandle vh, const OM::Vec3f& n) override {
    if (!valid(vh)) return;
    saw_normal = true;
    grow(mesh.normals, 0.0f);
    std::copy_n(n.data(), 3, &mesh.normals[3 * static_cast<std::size_t>(vh.idx())]);
  }
  void set_normal(OM::VertexHandle vh, const OM::Vec3d& n) override { set_normal(vh, OM::Vec3f(n)); }
  void set_color(OM::VertexHandle vh, const OM::Vec3uc& c) override {
    if (!valid(vh)) return;
    saw_color = true;
    grow(mesh.colors, std::uint8_t{0});
    std::copy_n(c.data(), 3, &mesh.colors[3 * static_cast<std::size_t>(vh.idx())]);
  }
  void set_color(OM::VertexHandle vh, const OM::Vec4uc& c) override {
    set_color(vh, OM::Vec3uc(c[0], c[1], c[2]));
  }
  void set_color(OM::VertexHandle vh, const OM::Vec3f& c) override {
    set_color(vh, to_bytes(c[0], c[1], c[2]));
  }
  void set_color(OM::VertexHandle vh, const OM::Vec4f& c) override {
    set_color(vh, to_bytes(c[0], c[1], c[2]));
  }

  std::size_t n_vertices() const override { return mesh.positions.size() / 3; }
  std::size_t n_faces() const override { return faces_; }
  std::size_t n_edges() const override { return 0; }
  void reserve(unsigned int vertices, unsigned int, unsigned int faces) override {
    // Header counts are untrusted: cap the reservation so a lying header cannot exhaust memory.
    constexpr unsigned int kMaxReserve = 1u << 24;
    mesh.positions.reserve(3 * std::size_t{std::min(vertices, kMaxReserve)});
    mesh.triangles.reserve(3 * std::size_t{std::min(faces, kMaxReserve)});
  }

  // Not needed by mtlod.
  OM::HalfedgeHandle add_edge(OM::VertexHandle, OM::VertexHandle) override { return OM::HalfedgeHandle(); }
  OM::FaceHandle add_face(OM::HalfedgeHandle) override { return OM::FaceHandle(); }
  void add_face_texcoords(OM::FaceHandle, OM::VertexHandle, const std::vector<OM::Vec2f>&) override {}
  void add_face_texcoords(OM::FaceHandle, OM::VertexHandle, const std::vector<OM::Vec3f>&) override {}
  void set_face_texindex(OM::FaceHandle, int) override {}
  void set_halfedge(OM::VertexHandle, OM::HalfedgeHandle) override {}
  void set_texcoord(OM::VertexHandle, const OM::Vec2f&) override {}
  void set_texcoord(OM::VertexHandle, const OM::Vec3f&) override {}
  void set_texcoord(OM::HalfedgeHandle, const OM::Vec2f&) override {}
  void set_texcoord(OM::HalfedgeHandle, const OM::Vec3f&) override {}
  void set_status(OM::VertexHandle, const OM::Attributes::StatusInfo&) override {}
  void set_status(OM::HalfedgeHandle, const OM::Attributes::StatusInfo&) override {}
  void set_status(OM::EdgeHandle, const OM::Attributes::StatusInfo&) override {}
  void set_status(OM::FaceHandle, const OM::Attributes::StatusInfo&) override {}
  void set_next(OM::HalfedgeHandle, OM::HalfedgeHandle) override {}
  void set_face(OM::HalfedgeHandle, OM::FaceHandle) override {}
  void request_face_texcoords2D() override {}
  void set_color(OM::EdgeHandle, const OM::Vec3uc&) override {}
  void set_color(OM::EdgeHandle, const OM::Vec4uc&) override {}
  void set_color(OM::EdgeHandle, const OM::Vec3f&) override {}
  void set_color(OM::EdgeHandle, const OM::Vec4f&) override {}
  void set_normal(OM::FaceHandle, const OM::Vec3f&) override {}
  void set_normal(OM::FaceHandle, const OM::Vec3d&) override {}
  void set_color(OM::FaceHandle, const OM::Vec3uc&) override {}
  void set_color(OM::FaceHandle, const OM::Vec4uc&) override {}
  void set_color(OM::FaceHandle, const OM::Vec3f&) override {}
  void set_color(OM::FaceHandle, const OM::Vec4f&) override {}
  void add_texture_information(int, std::string) override {}

 private:
  std::size_t faces_ = 0;

  void note(std::string message) {
    if (first_error.empty()) first_error = std::move(message);
  }
  bool valid(OM::VertexHandle vh) const {
    return vh.idx() >= 0 && static_cast<std::size_t>(vh.idx()) < mesh.positions.size() / 3;
  }
  template <class T>
  void grow(std::vector<T>& values, T fill) const {
    if (values.size() < mesh.positions.size()) values.resize(mesh.positions.size(), fill);
  }
  static OM::Vec3uc to_bytes(float r, float g, float b) {
    auto byte = [](float x) {
      return static_cast<unsigned char>(
          std::lround(std::clamp(std::isfinite(x) ? x : 0.0f, 0.0f, 1.0f) * 255.0f));
    };
    return OM::Vec3uc(byte(r), byte(g), byte(b));
  }
};

std::string lower_extension(const std::filesystem::path& path) {
  std::string ext = path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  return ext;
}

// Binary PLY readers in OpenMesh do not notice a file that ends early: they read zeros past the
// end. Check the byte count against the header before parsing (fixed-size vertex records plus,
// for faces, at least the list-length byte of every face).
Status check_binary_ply_size(const std::filesystem::path& path, std::uintmax_t file_size) {
  std::ifstream in(path, std::ios::binary);
  std::string line, format;
  std::uintmax_t header_bytes = 0;
  struct Element {
    std::string name;
    std::uintmax_t count = 0;
    std::uintmax_t fixed_bytes = 0;  // per record, lists count their length field only
  };
  std::vector<Element> elements;
  auto type_size = [](const std::string& t) -> int {
    if (t == "char" || t == "uchar" || t == "int8" || t == "uint8") return 1;
    if (t == "short" || t == "ushort" || t == "int16" || t == "uint16") return 2;
    if (t == "int" || t == "uint" || t == "float" || t == "int32" || t == "uint32" || t == "float32")
      return 4;
    if (t == "double" || t == "float64") return 8;
    return 0;
  };
  while (std::getline(in, line)) {
    header_bytes += line.size() + 1;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.rfind("format ", 0) == 0) format = line.substr(7, line.find(' ', 7) - 7);
    if (line.rfind("element ", 0) == 0) {
      Element e;
      const auto space = line.find(' ', 8);
      e.name = line.substr(8, space - 8);
      try {
        e.count = std::stoull(line.substr(space + 1));
      } catch (const std::exception&) {
        return make_error(ErrorCode::kCorrupt,
                          fmt::format("{}: bad PLY element line '{}'", path.string(), line));
      }
      elements.push_back(e);
    }
    if (line.rfind("property ", 0) == 0 && !elements.empty()) {
      char a[64] = {}, b[64] = {};
      if (line.rfind("property list ", 0) == 0) {
        if (std::sscanf(line.c_str(), "property list %63s %63s", a, b) == 2)
          elements.back().fixed_bytes += type_size(a);
      } else if (std::sscanf(line.c_str(), "property %63s", a) == 1) {
        elements.back().fixed_bytes += type_size(a);
      }
    }
    if (line == "end_header") break;
    if (header_bytes > (1u << 20)) break;
  }
  if (format != "binary_little_endian" && format != "binary_big_endian") return Ok{};
  std::uintmax_t needed = header_bytes;
  for (const Element& e : elements) {
    if (e.fixed_bytes != 0 && e.count > (UINTMAX_MAX - needed) / e.fixed_bytes) {
      return make_error(ErrorCode::kCorrupt, fmt::format("{}: element '{}' count {} is impossible",
                                                         path.string(), e.name, e.count));
    }
    needed += e.count * e.fixed_bytes;
  }
  if (file_size < needed) {
    return make_error(
        ErrorCode::kCorrupt,
        fmt::format("{}: truncated binary PLY: the header needs at least {} bytes, the file has {}",
                    path.string(), needed, file_size));
  }
  return Ok{};
}

// The file exists, is a non-empty readable file of a known format, and (for binary PLY) is not
// truncated. Returns its extension in lower case.
Result<std::string> check_mesh_file(const std::filesystem::path& path, const std::string& name) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) {
    return make_error(ErrorCode::kNotFound, fmt::format("{}: no such file", name));
  }
  if (std::filesystem::is_directory(path, ec)) {
    return make_error(ErrorCode::kInvalidArgument, fmt::format("{}: is a directory, not a mesh file", name));
  }
  const std::uintmax_t size = std::filesystem::file_size(path, ec);
  if (ec) return make_error(ErrorCode::kIoError, fmt::format("{}: cannot read size: {}", name, ec.message()));
  if (size == 0) return make_error(ErrorCode::kCorrupt, fmt::format("{}: empty file", name));
  if (!std::ifstream(path, std::ios::binary)) {
    return make_error(ErrorCode::kIoError, fmt::format("{}: cannot open for reading", name));
  }
  const std::string ext = lower_extension(path);
  if (ext != ".ply" && ext != ".obj" && ext != ".off" && ext != ".stl") {
    return make_error(ErrorCode::kUnsupported,
                      fmt::format("{}: unknown mesh format '{}' (use .ply, .obj, .off or .stl)", name, ext));
  }
  if (ext == ".ply") MTLOD_RETURN_IF_ERROR(check_binary_ply_size(path, size));
  return ext;
}

// The mesh read has vertices and faces, finite positions and a vertex count under the limit.
Status check_read_mesh(const model::Mesh& mesh, const std::string& name) {
  if (mesh.vertex_count() == 0) return make_error(ErrorCode::kCorrupt, fmt::format("{}: no vertices", name));
  if (mesh.triangle_count() == 0) return make_error(ErrorCode::kCorrupt, fmt::format("{}: no faces", name));
  // Readers set points through several importer calls; check them all once here.
  for (std::size_t v = 0; v < mesh.vertex_count(); ++v) {
    const float* p = &mesh.positions[3 * v];
    if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2])) {
      return make_error(
          ErrorCode::kCorrupt,
          fmt::format("{}: vertex {} has a non-finite coordinate ({}, {}, {})", name, v, p[0], p[1], p[2]));
    }
  }
  if (mesh.vertex_count() > UINT32_MAX / 2) {
    return make_error(ErrorCode::kLimitExceeded,
                      fmt::format("{}: {} vertices is over the limit", name, mesh.vertex_count()));
  }
  return Ok{};
}

}  // namespace

Result<LoadedMesh> load_mesh(const std::filesystem::path& path, const LoadOptions& options) {
  const std::string name = path.string();
  MTLOD_TRY(const std::string ext, check_mesh_file(path, name));

  FlatImporter importer;
  OM::IO::Options read_options;
  read_options += OM::IO::Options::VertexNormal;
  read_options += OM::IO::Options::VertexColor;
  // OpenMesh reports parse problems on its error stream; we report them ourselves, once.
  ::omerr().disable();
  ::omlog().disable();
  const bool read_ok = OM::IO::IOManager().read(name, importer, read_options);
  ::omerr().enable();
  if (!importer.first_error.empty()) {
    return make_error(ErrorCode::kCorrupt, fmt::format("{}: {}", name, importer.first_error));
  }
  if (!read_ok) {
    return make_error(ErrorCode::kCorrupt,
                      fmt::format("{}: not a readable {} file (corrupt or truncated)", name, ext.substr(1)));
  }
  LoadedMesh loaded;
  loaded.mesh = std::move(importer.mesh);
  model::Mesh& mesh = loaded.mesh;
  MTLOD_RETURN_IF_ERROR(check_read_mesh(mesh, name));
  // Attributes the reader set for some vertices only are padded to every vertex; attributes it did
  // not set at all are dropped rather than kept as zeros.
  if (!importer.saw_normal || !read_options.check(OM::IO::Options::VertexNormal))
    mesh.normals.clear();
  else
    mesh.normals.resize(mesh.positions.size(), 0.0f);
  if (!importer.saw_color || !read_options.check(OM::IO::Options::VertexColor))
    mesh.colors.clear();
  else
    mesh.colors.resize(mesh.positions.size(), 0);
  loaded.polygons_triangulated = importer.polygons_triangulated;

  loaded.input_topology = model::analyze_topology(mesh.positions, mesh.triangles);
  // OpenMesh's STL reader already merges equal corners; report that weld as ours.
  if (ext == ".stl") loaded.cleanup.welded_vertices = 3 * mesh.triangle_count() - mesh.vertex_count();
  if (options.clean) {
    model::CleanupOptions cleanup = options.cleanup;
    if (ext == ".stl") cleanup.weld_duplicate_positions = true;  // STL stores each corner on its own
    const std::size_t welded_by_reader = loaded.cleanup.welded_vertices;
    loaded.cleanup = model::clean_mesh(mesh, cleanup);
    loaded.cleanup.welded_vertices += welded_by_reader;
    if (mesh.triangle_count() == 0) {
      return make_error(ErrorCode::kCorrupt, fmt::format("{}: every triangle is degenerate", name));
    }
  }
  return loaded;
}

namespace {

// One PLY writer in the tree: PlyWriter, given the whole mesh at once.
Status write_ply(const std::filesystem::path& path, const model::Mesh& mesh) {
  const std::size_t n = mesh.vertex_count();
  const std::size_t t = mesh.triangle_count();
  MTLOD_TRY(PlyWriter writer, PlyWriter::create(path, n, t, mesh.has_normals(), mesh.has_colors()));
  MTLOD_RETURN_IF_ERROR(
      writer.write_vertices(std::span(mesh.positions).first(3 * n), mesh.normals, mesh.colors));
  MTLOD_RETURN_IF_ERROR(writer.write_triangles(std::span(mesh.triangles).first(3 * t)));
  return writer.close();
}

Status write_obj(const std::filesystem::path& path, const model::Mesh& mesh) {
  std::FILE* f = std::fopen(path.string().c_str(), "wb");
  if (!f) return make_error(ErrorCode::kIoError, fmt::format("{}: cannot open for writing", path.string()));
  fmt::memory_buffer out;
  bool ok = true;
  auto flush = [&] {
    ok = ok && std::fwrite(out.data(), 1, out.size(), f) == out.size();
    out.clear();
  };
  fmt::format_to(std::back_inserter(out), "# written by mtlod\n");
  // fmt prints the shortest decimal that reads back to the same float: positions round-trip exactly.
  for (std::size_t v = 0; v < mesh.vertex_count(); ++v) {
    fmt::format_to(std::back_inserter(out), "v {} {} {}\n", mesh.positions[3 * v], mesh.positions[3 * v + 1],
                   mesh.positions[3 * v + 2]);
    if (out.size() > (1u << 20)) flush();
  }
  for (std::size_t v = 0; v < mesh.vertex_count() && mesh.has_normals(); ++v) {
    fmt::format_to(std::back_inserter(out), "vn {} {} {}\n", mesh.normals[3 * v], mesh.normals[3 * v + 1],
                   mesh.normals[3 * v + 2]);
    if (out.size() > (1u << 20)) flush();
  }
  for (std::size_t t = 0; t < mesh.triangle_count(); ++t) {
    const std::uint32_t a = mesh.triangles[3 * t] + 1, b = mesh.triangles[3 * t + 1] + 1,
                        c = mesh.triangles[3 * t + 2] + 1;
    if (mesh.has_normals()) {
      fmt::format_to(std::back_inserter(out), "f {0}//{0} {1}//{1} {2}//{2}\n", a, b, c);
    } else {
      fmt::format_to(std::back_inserter(out), "f {} {} {}\n", a, b, c);
    }
    if (out.size() > (1u << 20)) flush();
  }
  flush();
  ok = (std::fclose(f) == 0) && ok;
  if (!ok) return make_error(ErrorCode::kIoError, fmt::format("{}: write failed", path.string()));
  return Ok{};
}

}  // namespace

Status save_mesh(const std::filesystem::path& path, const model::Mesh& mesh) {
  const std::string ext = lower_extension(path);
  if (ext == ".ply") return write_ply(path, mesh);
  if (ext == ".obj") return write_obj(path, mesh);
  return make_error(ErrorCode::kUnsupported,
                    fmt::format("{}: cannot write '{}' files (use .ply or .obj)", path.string(), ext));
}

}  // namespace mtlod::core::io
