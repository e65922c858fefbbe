// The out-of-core MT build (core/build/large_build.hpp; the method and its reasons: LARGE_BUILD.md).
//
// Phases, each a pass over files:
//   read_vertices   the PLY's vertices into raw arrays (positions, normals, colours) on disk
//   read_faces      its faces, dropping degenerate ones, into a raw face file; a histogram of the
//                   faces' centroid cells in Morton order
//   check_normals   whether the file's own normals are all usable (finite, not zero-length); if
//                   not, or there are none, angle-weighted normals (core/build/vertex_normals.hpp) are
//                   summed over every leaf's faces as the leaves are simplified
//   choose_leaves   runs of cells of at most block_triangles faces each: the leaf blocks
//   distribute      every face into its leaf's file; per vertex the range of leaves around it
//   simplify        stages level by level: leaves, then merges of two neighbouring stages' remains,
//                   each with the vertices whose faces reach outside it locked (simplify_block)
//   finish_normals  the normals file: the file's own made unit length, computed ones where needed
//   assemble        nodes numbered as build_mt numbers them, triangles placed by creating node
//                   through bucket files, the arrays written into the .mt file and its checksum
#include "core/build/large_build.hpp"

#include <fcntl.h>
#include <sys/mman.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <numeric>
#include <optional>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "core/build/vertex_normals.hpp"
#include "core/io/ply_stream.hpp"
#include "core/model/mesh_cleanup.hpp"
#include "core/model/mt_format.hpp"
#include "core/util/grow_only_vector.hpp"
#include "core/util/radix_sort.hpp"
#include "fmt/format.h"

namespace mtlod::core::build {
namespace {

namespace fs = std::filesystem;

// Estimated peak bytes: per face of a stage (the builder's arrays, the block's input and output),
// per vertex of the model while blocks are simplified (leaf ranges), per point a stage carries (the
// pool with its slack and a compaction's copy), and per vertex while the MT is assembled. Checked
// against peak RSS under several limits (tests/bench/BENCHMARKS.md, "Scaling").
constexpr std::uint64_t kStageBytesPerFace = 450;
constexpr std::uint64_t kBytesPerVertex = 8;
constexpr std::uint64_t kBytesPerPoint = 48;
// The process itself: code, libraries, chunk buffers, allocator slack and huge-page rounding.
constexpr std::uint64_t kFixedBytes = std::uint64_t{128} << 20;
constexpr std::uint64_t kAssemblyBytesPerVertex = 48;
// The least and most faces a leaf block gets when derived from the memory limit.
constexpr std::uint64_t kMinBlockTriangles = 4096;
constexpr std::uint64_t kMaxBlockTriangles = std::uint64_t{1} << 20;
// Centroid cells: 2^7 per axis, numbered in Morton order (21 bits): fine enough for blocks of a
// few thousand faces, and the two per-cell arrays take 16 MiB.
constexpr int kCellBits = 7;
constexpr std::size_t kCells = std::size_t{1} << (3 * kCellBits);
// Leaf files written at once by one pass over the faces (each with its own buffer).
constexpr std::size_t kLeavesPerPass = 256;
constexpr std::size_t kChunkTriangles = std::size_t{1} << 20;
// Triangles per bucket of the placement pass: 16 bytes each on disk and in memory when read back,
// and 12 more when written; as many as the memory limit leaves room for, within these bounds.
constexpr std::uint64_t kBucketBytesPerTriangle = 28;
constexpr std::uint64_t kMinBucketTriangles = std::uint64_t{1} << 20;
constexpr std::uint64_t kMaxBucketTriangles = std::uint64_t{16} << 20;
// A stage below the root leaves this fraction of its faces to its parent: a merge then takes half
// of what its two children took, so each level has half the faces of the one below and all levels
// together simplify about twice the input (halving would make every level as big as the first).
constexpr std::size_t kStageReduction = 4;
// A creator reference: (stage << 32) | collapse tag; kPending until a collapse takes the triangle.
constexpr std::uint64_t kPending = ~std::uint64_t{0};

std::uint64_t ref_of(std::uint32_t stage, std::uint32_t index) {
  return std::uint64_t{stage} << 32 | index;
}
std::uint32_t ref_stage(std::uint64_t ref) {
  return std::uint32_t(ref >> 32);
}
std::uint32_t ref_index(std::uint64_t ref) {
  return std::uint32_t(ref);
}

Error io_error(const fs::path& path, const char* what) {
  return make_error(ErrorCode::kIoError,
                    fmt::format("{}: cannot {}: {}", path.string(), what, std::strerror(errno)));
}

// A temporary directory, removed with everything in it when this goes.
class TempDir {
 public:
  static Result<TempDir> create(const fs::path& parent) {
    std::string pattern = (parent / "mtlod-build-XXXXXX").string();
    if (::mkdtemp(pattern.data()) == nullptr) return io_error(parent, "create a temporary directory in");
    return TempDir(pattern);
  }
  TempDir(TempDir&& other) noexcept : path_(std::exchange(other.path_, {})) {}
  TempDir& operator=(TempDir&&) = delete;
  ~TempDir() {
    std::error_code ec;
    if (!path_.empty()) fs::remove_all(path_, ec);
  }
  fs::path operator/(const std::string& name) const { return path_ / name; }
  const fs::path& path() const { return path_; }
  // Bytes in the directory now.
  std::uint64_t bytes() const {
    std::uint64_t total = 0;
    std::error_code ec;
    for (const auto& entry : fs::directory_iterator(path_, ec))
      if (entry.is_regular_file(ec)) total += entry.file_size(ec);
    return total;
  }

 private:
  explicit TempDir(fs::path path) : path_(std::move(path)) {}
  fs::path path_;
};

// A buffered file written front to back (or appended to).
class Writer {
 public:
  static Result<Writer> open(const fs::path& path, bool append = false, std::size_t buffer = 1 << 20) {
    std::FILE* f = std::fopen(path.string().c_str(), append ? "ab" : "wb");
    if (f == nullptr) return io_error(path, "open for writing");
    Writer w(path, f);
    w.buffer_.resize(buffer);
    std::setvbuf(f, w.buffer_.data(), _IOFBF, w.buffer_.size());
    return w;
  }
  Writer(Writer&& other) noexcept
      : path_(std::move(other.path_)),
        file_(std::exchange(other.file_, nullptr)),
        buffer_(std::move(other.buffer_)) {}
  Writer& operator=(Writer&&) = delete;
  ~Writer() {
    if (file_) std::fclose(file_);
  }
  template <class T>
  Status write(std::span<const T> values) {
    if (values.empty()) return Ok{};
    if (std::fwrite(values.data(), sizeof(T), values.size(), file_) != values.size())
      return io_error(path_, "write");
    return Ok{};
  }
  template <class T>
  Status write(const std::vector<T>& values) {
    return write(std::span<const T>(values));
  }
  Status close() {
    std::FILE* f = std::exchange(file_, nullptr);
    if (f && std::fclose(f) != 0) return io_error(path_, "write");
    return Ok{};
  }

 private:
  Writer(fs::path path, std::FILE* file) : path_(std::move(path)), file_(file) {}
  fs::path path_;
  std::FILE* file_;
  std::vector<char> buffer_;
};

// The whole file as an array of T; a missing file reads as empty when allowed.
template <class T>
Result<std::vector<T>> read_array(const fs::path& path, bool may_be_missing = false) {
  std::error_code ec;
  if (may_be_missing && !fs::exists(path, ec)) return std::vector<T>{};
  const std::uint64_t bytes = fs::file_size(path, ec);
  if (ec) return io_error(path, "read the size of");
  std::vector<T> values(bytes / sizeof(T));
  std::FILE* f = std::fopen(path.string().c_str(), "rb");
  if (f == nullptr) return io_error(path, "open");
  const bool ok = std::fread(values.data(), sizeof(T), values.size(), f) == values.size();
  std::fclose(f);
  if (!ok) return io_error(path, "read");
  return values;
}

// Appends the whole file to values (read straight into place: a stage's points can be most of memory).
Status append_file(const fs::path& path, util::GrowOnlyVector<float>& values) {
  std::error_code ec;
  const std::uint64_t bytes = fs::file_size(path, ec);
  if (ec) return io_error(path, "read the size of");
  const std::size_t at = values.size(), count = bytes / sizeof(float);
  values.resize(at + count);
  std::FILE* f = std::fopen(path.string().c_str(), "rb");
  if (f == nullptr) return io_error(path, "open");
  const bool ok = std::fread(values.data() + at, sizeof(float), count, f) == count;
  std::fclose(f);
  if (!ok) return io_error(path, "read");
  return Ok{};
}

Status pwrite_all(int fd, const fs::path& path, const void* data, std::uint64_t bytes, std::uint64_t offset) {
  const auto* p = static_cast<const std::uint8_t*>(data);
  while (bytes > 0) {
    const ssize_t n = ::pwrite(fd, p, std::min<std::uint64_t>(bytes, std::uint64_t{1} << 30), off_t(offset));
    if (n <= 0) return io_error(path, "write");
    p += n, bytes -= std::uint64_t(n), offset += std::uint64_t(n);
  }
  return Ok{};
}

// Writes a whole array at offset.
template <class Array>
Status put_array(int fd, const fs::path& path, const Array& values, std::uint64_t offset) {
  return pwrite_all(fd, path, values.data(), values.size() * sizeof(values[0]), offset);
}

// A read-only map of a file (the positions as floats; normals and colours as bytes). The kernel
// pages it in on use, and release() drops the pages from this process so that the model's vertex
// arrays do not stay resident.
class MappedFile {
 public:
  static Result<MappedFile> open(const fs::path& path) {
    const int fd = ::open(path.string().c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) return io_error(path, "open");
    std::error_code ec;
    const std::uint64_t bytes = fs::file_size(path, ec);
    void* p = bytes == 0 ? nullptr : ::mmap(nullptr, bytes, PROT_READ, MAP_SHARED, fd, 0);
    ::close(fd);
    if (p == MAP_FAILED) return io_error(path, "map");
    return MappedFile(static_cast<const float*>(p), bytes);
  }
  MappedFile(MappedFile&& other) noexcept
      : data_(std::exchange(other.data_, nullptr)), bytes_(std::exchange(other.bytes_, 0)) {}
  MappedFile& operator=(MappedFile&&) = delete;
  ~MappedFile() {
    if (data_) ::munmap(const_cast<float*>(data_), bytes_);
  }
  const float* data() const { return data_; }
  const std::uint8_t* bytes() const { return reinterpret_cast<const std::uint8_t*>(data_); }
  void release() const {
    if (data_) ::madvise(const_cast<float*>(data_), bytes_, MADV_DONTNEED);
  }

 private:
  MappedFile(const float* data, std::uint64_t bytes) : data_(data), bytes_(bytes) {}
  const float* data_;
  std::uint64_t bytes_;
};

std::uint32_t spread_bits(std::uint32_t x) {
  // Up to 8 bits to every third bit of 24.
  x &= 0xff;
  x = (x | (x << 8)) & 0x0f00f;
  x = (x | (x << 4)) & 0x0c30c3;
  x = (x | (x << 2)) & 0x249249;
  return x;
}

// A stage: a leaf block, or the merge of two stages' remains. Stages are numbered level by level,
// leaves first, which is the order of their collapses in the simplification sequence.
struct Stage {
  std::uint32_t lo = 0, hi = 0;  // the leaves it covers
  std::uint32_t children[2] = {0, 0};
  bool leaf = true;
  bool root = false;
  // Passes its children's remains up unchanged: once a level's faces fit in one block, only the
  // root simplifies them, in one error order for the whole model.
  bool deferred = false;
  // Filled when it has run.
  std::uint32_t owned = 0;   // triangles it owns: a leaf's kept input faces, then those it made
  std::uint32_t inputs = 0;  // of them, the kept input faces (leaves only)
  std::uint32_t collapses = 0;
  std::uint32_t input_faces = 0;
  std::uint32_t remaining = 0;
  std::uint64_t remaining_points = 0;
  std::uint64_t duplicates = 0;  // input faces dropped (leaves only)
  std::size_t complex_vertices = 0;
  std::size_t topology_collapses = 0;
  float topology_error = std::numeric_limits<float>::infinity();
  std::size_t stacking_collapses = 0;
  float stacking_error = std::numeric_limits<float>::infinity();
};

// A face a stage leaves to its parent (28 bytes in the .rem file; its points follow in .pts).
struct RemainingFace {
  std::uint32_t v[3];
  std::uint32_t points;
  std::uint64_t origin;  // (stage, index) of the triangle among that stage's owned triangles
  float error;
  std::uint32_t pad = 0;
};
static_assert(sizeof(RemainingFace) == 32);

// A triangle placed in the file: its id, its 2nd and 3rd corner and its remover.
struct Placed {
  std::uint32_t id, c1, c2, remover;
};

// The MT's arrays and counts as assemble's steps fill them, each freed once written.
struct Assembly {
  std::vector<std::uint64_t> collapse_base;  // per stage, its first collapse in sequence order
  std::uint64_t triangles = 0;               // owned by all stages
  std::uint32_t node_count = 0;
  std::vector<std::uint32_t> node_of;    // per collapse in sequence order, its node
  std::vector<std::uint32_t> vertex_id;  // per input vertex, its MT id (kNoVertex: left out)
  std::uint32_t used_vertices = 0, root_vertices = 0;
  std::vector<std::uint32_t> node_vertex;
  std::vector<float> node_error;
  std::vector<std::uint32_t> parents;  // for_parents's list
  std::vector<std::uint32_t> triangle_offsets, parent_offsets;
  model::MtCounts counts;
  model::MtLayout layout{};
  std::vector<std::uint32_t> node_parents, root_first_corner;
  std::uint64_t bucket_triangles = 0, buckets = 0;  // placement: triangles per bucket file, and files
};

class LargeBuilder {
 public:
  LargeBuilder(const fs::path& input, const fs::path& output, const LargeBuildOptions& options, TempDir& temp)
      : input_(input), output_(output), options_(options), temp_(temp) {}

  Status run(LargeBuildStats& stats);

 private:
  fs::path file(const std::string& name) const { return temp_ / name; }
  fs::path stage_file(std::uint32_t s, const char* kind) const {
    return temp_ / fmt::format("s{}.{}", s, kind);
  }
  void progress(const char* phase, double fraction) const {
    if (options_.progress) options_.progress(options_.progress_user, phase, fraction);
  }
  void note_temp() { stats_->temp_bytes = std::max(stats_->temp_bytes, temp_.bytes()); }

  Status read_vertices(io::PlyReader& reader);
  Status read_faces(io::PlyReader& reader);
  Status check_normals();
  Status finish_normals();
  Status choose_leaves();
  Status distribute();
  void plan_stages();
  Status simplify();
  Status run_stage(std::uint32_t s, bool parallel);
  Status pass_up(std::uint32_t s);
  // run_stage's steps: the block's faces from its leaf file or its children's remains, its vertices,
  // and after simplify_block the files the assembly and the parent read.
  Status read_leaf(std::uint32_t s, bool parallel, std::vector<std::uint32_t>& global,
                   std::vector<std::uint64_t>& origin);
  void add_leaf_normals(const std::vector<std::uint32_t>& global, std::size_t out, bool parallel);
  Status read_merge(std::uint32_t s, BlockInput& block, std::vector<std::uint32_t>& global,
                    std::vector<std::uint64_t>& origin);
  std::vector<std::uint32_t> index_block(std::uint32_t s, const std::vector<std::uint32_t>& global,
                                         BlockInput& block) const;
  Status write_collapses(std::uint32_t s, const BlockOutput& result,
                         const std::vector<std::uint32_t>& vertices);
  Status write_owned(std::uint32_t s, const std::vector<std::uint32_t>& global,
                     const std::vector<std::uint32_t>& vertices, BlockOutput& result);
  Status write_creators(std::uint32_t s, std::size_t face_count, const std::vector<std::uint64_t>& origin,
                        const BlockOutput& result);
  Status write_remains(std::uint32_t s, std::size_t face_count, const std::vector<std::uint32_t>& global,
                       const std::vector<std::uint64_t>& origin, const BlockOutput& result);
  Status assemble();
  // assemble's steps, in order.
  Status number_collapses(Assembly& a);
  Result<std::vector<std::uint32_t>> load_creators(const Assembly& a, std::uint32_t s) const;
  template <class Each>
  void for_parents(Assembly& a, std::uint32_t s, const std::vector<std::uint32_t>& creators,
                   const std::vector<std::uint32_t>& made_by, const Each& each) const;
  Status count_nodes(Assembly& a);
  Status place_triangles(Assembly& a);
  Status write_file(Assembly& a);
  Status write_vertices(Assembly& a, int fd, const fs::path& partial);
  Status write_triangles(const Assembly& a, int fd, const fs::path& partial);

  std::uint32_t cell_of(const std::uint32_t* t) const {
    const float* p[3] = {&positions_->data()[3 * std::size_t{t[0]}],
                         &positions_->data()[3 * std::size_t{t[1]}],
                         &positions_->data()[3 * std::size_t{t[2]}]};
    std::uint32_t code = 0;
    for (int k = 0; k < 3; ++k) {
      const float c = (p[0][k] + p[1][k] + p[2][k]) / 3.0f;
      const float x = (c - lo_[k]) * scale_;
      const std::uint32_t cell = std::uint32_t(std::clamp(x, 0.0f, float((1 << kCellBits) - 1)));
      code |= spread_bits(cell) << k;
    }
    return code;
  }

  fs::path input_, output_;
  LargeBuildOptions options_;
  TempDir& temp_;
  LargeBuildStats* stats_ = nullptr;

  std::uint64_t limit_ = 0;  // bytes
  std::uint64_t vertex_count_ = 0;
  bool normals_ = false, colors_ = false;
  std::array<float, 3> lo_{}, hi_{};
  float scale_ = 1;  // cells per model unit
  std::optional<MappedFile> positions_;
  std::uint64_t faces_ = 0;  // kept after dropping degenerate ones
  std::vector<std::uint32_t> cell_count_;
  std::vector<std::uint32_t> leaf_of_cell_;
  std::uint32_t leaves_ = 0;
  // Per vertex, the fixed-point sums of computed normals (NormalAccumulator), while the leaves
  // are simplified; empty when the file's own normals are all usable.
  std::vector<std::int64_t> normal_sums_;
  // Per vertex, the first and last leaf holding one of its faces (kNoVertex: none).
  std::vector<std::uint32_t> leaf_lo_, leaf_hi_;
  std::vector<Stage> stages_;
  std::vector<std::vector<std::uint32_t>> levels_;
};

Status LargeBuilder::read_vertices(io::PlyReader& reader) {
  const io::PlyHeader& header = reader.header();
  vertex_count_ = header.vertex_count;
  normals_ = header.has_normals;
  colors_ = header.has_colors;
  if (vertex_count_ >= model::kNoVertex)
    return make_error(ErrorCode::kLimitExceeded,
                      fmt::format("{}: {} vertices exceed 32-bit MT ids", input_.string(), vertex_count_));
  MTLOD_TRY(Writer positions, Writer::open(file("positions")));
  std::optional<Writer> normals, colors;
  if (normals_) {
    MTLOD_TRY(Writer w, Writer::open(file("normals")));
    normals.emplace(std::move(w));
  }
  if (colors_) {
    MTLOD_TRY(Writer w, Writer::open(file("colors")));
    colors.emplace(std::move(w));
  }
  std::vector<float> p(3 * kChunkTriangles), n(normals_ ? 3 * kChunkTriangles : 0);
  std::vector<std::uint8_t> c(colors_ ? 3 * kChunkTriangles : 0);
  lo_.fill(std::numeric_limits<float>::infinity());
  hi_.fill(-std::numeric_limits<float>::infinity());
  std::uint64_t done = 0;
  for (;;) {
    MTLOD_TRY(const std::size_t count, reader.read_vertices(p, n, c));
    if (count == 0) break;
    for (std::size_t i = 0; i < 3 * count; ++i) {
      if (!std::isfinite(p[i]))
        return make_error(
            ErrorCode::kInvalidArgument,
            fmt::format("{}: vertex {} has a non-finite coordinate", input_.string(), done + i / 3));
      lo_[i % 3] = std::min(lo_[i % 3], p[i]);
      hi_[i % 3] = std::max(hi_[i % 3], p[i]);
    }
    MTLOD_RETURN_IF_ERROR(positions.write(std::span<const float>(p.data(), 3 * count)));
    if (normals) MTLOD_RETURN_IF_ERROR(normals->write(std::span<const float>(n.data(), 3 * count)));
    if (colors) MTLOD_RETURN_IF_ERROR(colors->write(std::span<const std::uint8_t>(c.data(), 3 * count)));
    done += count;
    progress("reading vertices", vertex_count_ ? double(done) / double(vertex_count_) : 1.0);
  }
  MTLOD_RETURN_IF_ERROR(positions.close());
  if (normals) MTLOD_RETURN_IF_ERROR(normals->close());
  if (colors) MTLOD_RETURN_IF_ERROR(colors->close());
  float extent = 0;
  for (int k = 0; k < 3; ++k) extent = std::max(extent, hi_[k] - lo_[k]);
  scale_ = extent > 0 ? float(1 << kCellBits) / extent : 1.0f;
  MTLOD_TRY(MappedFile mapped, MappedFile::open(file("positions")));
  positions_.emplace(std::move(mapped));
  return Ok{};
}

Status LargeBuilder::read_faces(io::PlyReader& reader) {
  MTLOD_TRY(Writer faces, Writer::open(file("faces")));
  std::vector<std::uint32_t> chunk(3 * kChunkTriangles), kept;
  kept.reserve(chunk.size());
  cell_count_.assign(kCells, 0);
  const std::span<const float> positions(positions_->data(), 3 * vertex_count_);
  const std::uint64_t file_faces = std::max<std::uint64_t>(reader.header().face_count, 1);
  std::uint64_t read = 0;
  for (;;) {
    MTLOD_TRY(const std::size_t count, reader.read_triangles(chunk));
    if (count == 0) break;
    kept.clear();
    for (std::size_t i = 0; i < count; ++i) {
      const std::uint32_t* t = &chunk[3 * i];
      if (model::is_degenerate_triangle(positions, t)) {
        ++stats_->dropped_degenerate;
        continue;
      }
      kept.insert(kept.end(), t, t + 3);
      ++cell_count_[cell_of(t)];
    }
    stats_->input_triangles += count;
    faces_ += kept.size() / 3;
    MTLOD_RETURN_IF_ERROR(faces.write(kept));
    read = std::min(file_faces, read + count);
    progress("reading faces", double(read) / double(file_faces));
  }
  stats_->polygons_triangulated = reader.polygons_triangulated();
  MTLOD_RETURN_IF_ERROR(faces.close());
  // The MT holds every input triangle and those the collapses make (about twice as many more); the
  // exact count is checked once the stages have run.
  if (faces_ >= model::kNoFace / 2)
    return make_error(ErrorCode::kLimitExceeded,
                      fmt::format("{}: {} triangles exceed 32-bit MT ids", input_.string(), faces_));
  note_temp();
  return Ok{};
}

Status LargeBuilder::check_normals() {
  stats_->normals_given = normals_;
  stats_->normals_computed = vertex_count_;
  if (normals_) {
    MTLOD_TRY(const MappedFile given, MappedFile::open(file("normals")));
    std::uint64_t bad = 0;
    for (std::uint64_t v = 0; v < vertex_count_; ++v) bad += !usable_normal(given.data() + 3 * v);
    given.release();
    stats_->normals_computed = bad;
  }
  if (stats_->normals_computed > 0) normal_sums_.assign(3 * vertex_count_, 0);
  return Ok{};
}

Status LargeBuilder::finish_normals() {
  // Written through the page cache like every other stage file: a map of the output would need an
  // msync (tens of ms on the 871k dragon) to report write errors before its pages are dropped.
  const fs::path path = file("normals"), partial = file("normals.unit");
  std::optional<MappedFile> given;
  if (normals_) {
    MTLOD_TRY(MappedFile m, MappedFile::open(path));
    given.emplace(std::move(m));
  }
  MTLOD_TRY(Writer out, Writer::open(partial));
  std::vector<float> n(3 * kChunkTriangles);
  for (std::uint64_t begin = 0; begin < vertex_count_; begin += kChunkTriangles) {
    const std::uint64_t end = std::min<std::uint64_t>(vertex_count_, begin + kChunkTriangles);
    for (std::uint64_t v = begin; v < end; ++v) {
      float* q = &n[3 * (v - begin)];
      if (given) std::copy_n(given->data() + 3 * v, 3, q);
      if (!given || !usable_normal(q)) {
        NormalAccumulator::finish(std::span(normal_sums_).subspan(3 * v, 3), std::span(q, 3));
        continue;
      }
      make_unit(q);
    }
    MTLOD_RETURN_IF_ERROR(out.write(std::span<const float>(n.data(), 3 * (end - begin))));
  }
  MTLOD_RETURN_IF_ERROR(out.close());
  if (given) given->release();
  given.reset();
  std::error_code ec;
  fs::rename(partial, path, ec);
  if (ec) return io_error(path, "rename");
  std::vector<std::int64_t>().swap(normal_sums_);
  normals_ = true;
  return Ok{};
}

Status LargeBuilder::choose_leaves() {
  // Memory while blocks are simplified: the process, per vertex (leaf ranges) and, at the top
  // levels, every removed vertex carried as a point; what is left goes to the stages running at once.
  const std::uint64_t limit = limit_;
  const std::uint64_t fixed = kFixedBytes + vertex_count_ * (kBytesPerVertex + kBytesPerPoint) +
                              normal_sums_.size() * sizeof(std::int64_t);
  const std::uint64_t threads = std::max<std::size_t>(options_.threads, 1);
  std::uint64_t block = options_.block_triangles;
  if (block == 0) {
    const std::uint64_t least = fixed + threads * kMinBlockTriangles * kStageBytesPerFace;
    if (limit < least || limit < vertex_count_ * kAssemblyBytesPerVertex) {
      return make_error(
          ErrorCode::kLimitExceeded,
          fmt::format("{}: a memory limit of {} MiB is too small for {} vertices (at least {} MiB)",
                      input_.string(), limit >> 20, vertex_count_,
                      (std::max(least, vertex_count_ * kAssemblyBytesPerVertex) >> 20) + 1));
    }
    block =
        std::clamp((limit - fixed) / (threads * kStageBytesPerFace), kMinBlockTriangles, kMaxBlockTriangles);
  }
  stats_->block_triangles = block;
  leaf_of_cell_.assign(kCells, 0);
  std::uint64_t in_leaf = 0;
  std::uint32_t leaf = 0;
  for (std::size_t cell = 0; cell < kCells; ++cell) {
    const std::uint32_t n = cell_count_[cell];
    if (in_leaf > 0 && in_leaf + n > block) ++leaf, in_leaf = 0;
    leaf_of_cell_[cell] = leaf;
    in_leaf += n;
  }
  leaves_ = leaf + 1;
  std::vector<std::uint32_t>().swap(cell_count_);
  stats_->blocks = leaves_;
  return Ok{};
}

Status LargeBuilder::distribute() {
  leaf_lo_.assign(vertex_count_, model::kNoVertex);
  leaf_hi_.assign(vertex_count_, 0);
  std::vector<std::uint32_t> chunk(3 * kChunkTriangles);
  // One read of the face file per group of kLeavesPerPass leaves, so few files are open at once.
  for (std::uint32_t first = 0; first < leaves_; first += kLeavesPerPass) {
    const std::uint32_t last = std::min<std::uint32_t>(leaves_, first + kLeavesPerPass);
    std::vector<Writer> writers;
    writers.reserve(last - first);
    for (std::uint32_t leaf = first; leaf < last; ++leaf) {
      MTLOD_TRY(Writer w, Writer::open(file(fmt::format("leaf{}", leaf)), false, std::size_t{64} << 10));
      writers.push_back(std::move(w));
    }
    std::FILE* in = std::fopen(file("faces").string().c_str(), "rb");
    if (in == nullptr) return io_error(file("faces"), "open");
    std::size_t count;
    std::uint64_t done = 0;
    while ((count = std::fread(chunk.data(), 12, kChunkTriangles, in)) > 0) {
      for (std::size_t i = 0; i < count; ++i) {
        const std::uint32_t* t = &chunk[3 * i];
        const std::uint32_t leaf = leaf_of_cell_[cell_of(t)];
        if (leaf < first || leaf >= last) continue;
        if (auto written = writers[leaf - first].write(std::span<const std::uint32_t>(t, 3)); !written) {
          std::fclose(in);
          return written.take_error();
        }
        for (int k = 0; k < 3; ++k) {
          leaf_lo_[t[k]] = std::min(leaf_lo_[t[k]], leaf);
          leaf_hi_[t[k]] = std::max(leaf_hi_[t[k]], leaf);
        }
      }
      done += count;
      positions_->release();
      progress("partitioning", (double(first) + double(done) / double(std::max<std::uint64_t>(faces_, 1)) *
                                                    double(last - first)) /
                                   double(leaves_));
    }
    const bool failed = std::ferror(in) != 0;
    std::fclose(in);
    if (failed) return io_error(file("faces"), "read");
    for (Writer& w : writers) MTLOD_RETURN_IF_ERROR(w.close());
  }
  std::vector<std::uint32_t>().swap(leaf_of_cell_);
  note_temp();
  std::error_code ec;
  fs::remove(file("faces"), ec);
  return Ok{};
}

void LargeBuilder::plan_stages() {
  std::vector<std::uint32_t> current;
  for (std::uint32_t leaf = 0; leaf < leaves_; ++leaf) {
    Stage s;
    s.lo = s.hi = leaf;
    current.push_back(std::uint32_t(stages_.size()));
    stages_.push_back(s);
  }
  levels_.push_back(current);
  // Neighbouring stages merge in pairs; an odd one out waits for the next level unchanged.
  while (current.size() > 1) {
    std::vector<std::uint32_t> next, level;
    for (std::size_t i = 0; i < current.size(); i += 2) {
      if (i + 1 == current.size()) {
        next.push_back(current[i]);
        continue;
      }
      Stage s;
      s.leaf = false;
      s.children[0] = current[i];
      s.children[1] = current[i + 1];
      s.lo = stages_[current[i]].lo;
      s.hi = stages_[current[i + 1]].hi;
      next.push_back(std::uint32_t(stages_.size()));
      level.push_back(std::uint32_t(stages_.size()));
      stages_.push_back(s);
    }
    levels_.push_back(level);
    current = std::move(next);
  }
  stages_.back().root = true;
  stats_->stages = stages_.size();
  stats_->levels = levels_.size();
}

Status LargeBuilder::pass_up(std::uint32_t s) {
  Stage& stage = stages_[s];
  for (const char* kind : {"col", "own", "madeby", "cre"}) {
    MTLOD_TRY(Writer empty, Writer::open(stage_file(s, kind)));
    MTLOD_RETURN_IF_ERROR(empty.close());
  }
  for (const char* kind : {"rem", "pts"}) {
    MTLOD_TRY(Writer out, Writer::open(stage_file(s, kind)));
    for (const std::uint32_t child : stage.children) {
      MTLOD_TRY(const auto bytes, read_array<std::uint8_t>(stage_file(child, kind)));
      MTLOD_RETURN_IF_ERROR(out.write(bytes));
      std::error_code ec;
      fs::remove(stage_file(child, kind), ec);
    }
    MTLOD_RETURN_IF_ERROR(out.close());
  }
  for (const std::uint32_t child : stage.children) {
    stage.remaining += stages_[child].remaining;
    stage.remaining_points += stages_[child].remaining_points;
  }
  stage.input_faces = stage.remaining;
  return Ok{};
}

Status LargeBuilder::read_leaf(std::uint32_t s, bool parallel, std::vector<std::uint32_t>& global,
                               std::vector<std::uint64_t>& origin) {
  Stage& stage = stages_[s];
  MTLOD_TRY(global, read_array<std::uint32_t>(file(fmt::format("leaf{}", stage.lo))));
  // Duplicates (the same vertex set as an earlier face) lie in the same cell, so in the same leaf.
  const std::size_t count = global.size() / 3;
  // Each face's corners in increasing order and its index; the first face of each vertex set is
  // kept. Grouped by the lowest corner with a radix sort, then each group (a few faces: those whose
  // lowest corner is that vertex) sorted whole: a full sort of the leaf took twice as long.
  std::vector<std::array<std::uint32_t, 4>> keys(count), scratch;
  for (std::size_t f = 0; f < count; ++f) {
    std::array<std::uint32_t, 3> v = {global[3 * f], global[3 * f + 1], global[3 * f + 2]};
    std::sort(v.begin(), v.end());
    keys[f] = {v[0], v[1], v[2], std::uint32_t(f)};
  }
  util::radix_sort(keys, scratch, [](const std::array<std::uint32_t, 4>& k) { return k[0]; });
  std::vector<std::uint8_t> duplicate(count, 0);
  for (std::size_t begin = 0, end = 0; begin < count; begin = end) {
    for (end = begin + 1; end < count && keys[end][0] == keys[begin][0];) ++end;
    if (end - begin == 1) continue;
    std::sort(keys.begin() + std::ptrdiff_t(begin), keys.begin() + std::ptrdiff_t(end));
    for (std::size_t i = begin + 1; i < end; ++i)
      if (keys[i][1] == keys[i - 1][1] && keys[i][2] == keys[i - 1][2]) duplicate[keys[i][3]] = 1;
  }
  std::size_t out = 0;
  for (std::size_t f = 0; f < count; ++f) {
    if (duplicate[f]) continue;
    std::copy_n(&global[3 * f], 3, &global[3 * out]);
    ++out;
  }
  global.resize(3 * out);
  if (!normal_sums_.empty()) add_leaf_normals(global, out, parallel);
  stage.duplicates = count - out;
  stage.inputs = std::uint32_t(out);
  origin.resize(out);
  for (std::uint32_t f = 0; f < out; ++f) origin[f] = ref_of(s, f);
  std::error_code ec;
  fs::remove(file(fmt::format("leaf{}", stage.lo)), ec);
  return Ok{};
}

void LargeBuilder::add_leaf_normals(const std::vector<std::uint32_t>& global, std::size_t out,
                                    bool parallel) {
  NormalAccumulator normals(std::span<const float>(positions_->data(), 3 * vertex_count_), normal_sums_);
  if (parallel && options_.build.parallel_for != nullptr) {
    // A lone leaf: each task owns a range of vertices and goes over all the faces, adding only to
    // its own vertices, so no addition is atomic. A face is read once per range, which costs less
    // than the locked additions would (a scan's corners are mostly close in number, so most faces
    // fall in one range).
    struct Ranges {
      NormalAccumulator* normals;
      const std::uint32_t* faces;
      std::size_t count;
      std::uint64_t vertices;
    } ranges{&normals, global.data(), out, vertex_count_};
    constexpr std::size_t kRanges = 4;
    options_.build.parallel_for(
        options_.build.parallel_user, kRanges,
        [](void* opaque, std::size_t i) {
          const auto* r = static_cast<const Ranges*>(opaque);
          const auto lo = std::uint32_t(r->vertices * i / kRanges),
                     hi = std::uint32_t(r->vertices * (i + 1) / kRanges);
          for (std::size_t f = 0; f < r->count; ++f)
            r->normals->add_within(r->faces[3 * f], r->faces[3 * f + 1], r->faces[3 * f + 2], lo, hi);
        },
        &ranges);
  } else if (options_.build.parallel_for != nullptr) {
    // Leaves that run side by side meet in shared vertices: their additions are atomic, and the
    // fixed-point sums make the result independent of the order.
    for (std::size_t f = 0; f < out; ++f)
      normals.add_concurrently(global[3 * f], global[3 * f + 1], global[3 * f + 2]);
  } else {
    for (std::size_t f = 0; f < out; ++f) normals.add(global[3 * f], global[3 * f + 1], global[3 * f + 2]);
  }
}

Status LargeBuilder::read_merge(std::uint32_t s, BlockInput& block, std::vector<std::uint32_t>& global,
                                std::vector<std::uint64_t>& origin) {
  for (const std::uint32_t child : stages_[s].children) {
    MTLOD_TRY(const auto remains, read_array<RemainingFace>(stage_file(child, "rem")));
    MTLOD_RETURN_IF_ERROR(append_file(stage_file(child, "pts"), block.points));
    for (const RemainingFace& r : remains) {
      global.insert(global.end(), r.v, r.v + 3);
      origin.push_back(r.origin);
      block.face_error.push_back(r.error);
      block.face_points.push_back(r.points);
    }
    std::error_code ec;
    fs::remove(stage_file(child, "rem"), ec);
    fs::remove(stage_file(child, "pts"), ec);
  }
  return Ok{};
}

std::vector<std::uint32_t> LargeBuilder::index_block(std::uint32_t s,
                                                     const std::vector<std::uint32_t>& global,
                                                     BlockInput& block) const {
  const Stage& stage = stages_[s];
  // Block vertex ids: the distinct global ids in increasing order (corners sorted by global id).
  std::vector<std::uint32_t> vertices;
  block.mesh.triangles.resize(global.size());
  {
    std::vector<std::uint32_t> corners(global.size()), scratch;
    std::iota(corners.begin(), corners.end(), 0u);
    util::radix_sort(corners, scratch, [&](std::uint32_t corner) { return global[corner]; });
    for (const std::uint32_t corner : corners) {
      if (vertices.empty() || vertices.back() != global[corner]) vertices.push_back(global[corner]);
      block.mesh.triangles[corner] = std::uint32_t(vertices.size() - 1);
    }
  }
  block.mesh.positions.resize(3 * vertices.size());
  block.locked.resize(vertices.size());
  for (std::size_t l = 0; l < vertices.size(); ++l) {
    const std::uint32_t g = vertices[l];
    std::copy_n(&positions_->data()[3 * std::size_t{g}], 3, &block.mesh.positions[3 * l]);
    block.locked[l] = !(leaf_lo_[g] >= stage.lo && leaf_hi_[g] <= stage.hi);
  }
  return vertices;
}

Status LargeBuilder::write_collapses(std::uint32_t s, const BlockOutput& result,
                                     const std::vector<std::uint32_t>& vertices) {
  // Collapses: global u and error.
  stages_[s].collapses = std::uint32_t(result.collapse_u.size());
  MTLOD_TRY(Writer w, Writer::open(stage_file(s, "col")));
  std::vector<std::uint32_t> records(2 * result.collapse_u.size());
  for (std::size_t c = 0; c < result.collapse_u.size(); ++c) {
    records[2 * c] = vertices[result.collapse_u[c]];
    std::memcpy(&records[2 * c + 1], &result.collapse_error[c], 4);
  }
  MTLOD_RETURN_IF_ERROR(w.write(records));
  MTLOD_RETURN_IF_ERROR(w.close());
  return Ok{};
}

Status LargeBuilder::write_owned(std::uint32_t s, const std::vector<std::uint32_t>& global,
                                 const std::vector<std::uint32_t>& vertices, BlockOutput& result) {
  Stage& stage = stages_[s];
  // Owned triangles: a leaf's kept inputs, then the made ones; their creators where known here.
  const std::size_t made = result.made_by.size();
  stage.owned = std::uint32_t(stage.inputs + made);
  MTLOD_TRY(Writer own, Writer::open(stage_file(s, "own")));
  if (stage.leaf) MTLOD_RETURN_IF_ERROR(own.write(global));
  for (std::uint32_t& v : result.made_triangles) v = vertices[v];
  MTLOD_RETURN_IF_ERROR(own.write(result.made_triangles));
  MTLOD_RETURN_IF_ERROR(own.close());
  MTLOD_TRY(Writer made_by, Writer::open(stage_file(s, "madeby")));
  MTLOD_RETURN_IF_ERROR(made_by.write(result.made_by));
  MTLOD_RETURN_IF_ERROR(made_by.close());
  return Ok{};
}

Status LargeBuilder::write_creators(std::uint32_t s, std::size_t face_count,
                                    const std::vector<std::uint64_t>& origin, const BlockOutput& result) {
  const Stage& stage = stages_[s];
  std::vector<std::uint64_t> creators(stage.owned, kPending);
  // Updates for triangles earlier stages own, grouped by owner.
  std::vector<std::pair<std::uint32_t, std::array<std::uint32_t, 3>>> updates;
  for (std::size_t t = 0; t < result.taken_by.size(); ++t) {
    const std::uint32_t tag = result.taken_by[t];
    const std::uint64_t ref = tag == 0 ? kPending : ref_of(s, tag);
    if (t >= face_count) {
      creators[stage.inputs + (t - face_count)] = ref;
    } else if (ref_stage(origin[t]) == s) {
      creators[ref_index(origin[t])] = ref;
    } else if (tag != 0) {
      updates.push_back({ref_stage(origin[t]), {ref_index(origin[t]), s, tag}});
    }
  }
  {
    MTLOD_TRY(Writer w, Writer::open(stage_file(s, "cre")));
    MTLOD_RETURN_IF_ERROR(w.write(creators));
    MTLOD_RETURN_IF_ERROR(w.close());
  }
  std::stable_sort(updates.begin(), updates.end(),
                   [](const auto& a, const auto& b) { return a.first < b.first; });
  for (std::size_t i = 0; i < updates.size();) {
    const std::uint32_t owner = updates[i].first;
    // Stages running side by side cover disjoint leaves, so never append to the same owner's file.
    MTLOD_TRY(Writer w, Writer::open(stage_file(owner, "upd"), /*append=*/true));
    for (; i < updates.size() && updates[i].first == owner; ++i)
      MTLOD_RETURN_IF_ERROR(w.write(std::span<const std::uint32_t>(updates[i].second)));
    MTLOD_RETURN_IF_ERROR(w.close());
  }
  return Ok{};
}

Status LargeBuilder::write_remains(std::uint32_t s, std::size_t face_count,
                                   const std::vector<std::uint32_t>& global,
                                   const std::vector<std::uint64_t>& origin, const BlockOutput& result) {
  Stage& stage = stages_[s];
  std::vector<RemainingFace> remains(result.remaining.size());
  for (std::size_t i = 0; i < remains.size(); ++i) {
    const std::uint32_t t = result.remaining[i];
    RemainingFace& r = remains[i];
    const std::uint32_t* v = t < face_count ? &global[3 * std::size_t{t}]
                                            : &result.made_triangles[3 * std::size_t{t - face_count}];
    std::copy_n(v, 3, r.v);
    r.points = result.remaining_points[i];
    r.origin = t < face_count ? origin[t] : ref_of(s, stage.inputs + (t - face_count));
    r.error = result.remaining_error[i];
    stage.remaining_points += r.points;
  }
  stage.remaining = std::uint32_t(remains.size());
  MTLOD_TRY(Writer rem, Writer::open(stage_file(s, "rem")));
  MTLOD_RETURN_IF_ERROR(rem.write(remains));
  MTLOD_RETURN_IF_ERROR(rem.close());
  MTLOD_TRY(Writer pts, Writer::open(stage_file(s, "pts")));
  MTLOD_RETURN_IF_ERROR(pts.write(std::span<const float>(result.points)));
  MTLOD_RETURN_IF_ERROR(pts.close());
  return Ok{};
}

Status LargeBuilder::run_stage(std::uint32_t s, bool parallel) {
  Stage& stage = stages_[s];
  if (stage.deferred) return pass_up(s);
  BlockInput block;
  std::vector<std::uint32_t> global;  // the block's faces over global vertex ids
  std::vector<std::uint64_t> origin;  // per face: (stage, index) of the triangle
  if (stage.leaf) {
    MTLOD_RETURN_IF_ERROR(read_leaf(s, parallel, global, origin));
  } else {
    MTLOD_RETURN_IF_ERROR(read_merge(s, block, global, origin));
  }
  const std::size_t face_count = global.size() / 3;
  stage.input_faces = std::uint32_t(face_count);
  const std::vector<std::uint32_t> vertices = index_block(s, global, block);

  BuildOptions build = options_.build;
  build.progress = nullptr;
  if (!parallel) build.parallel_for = nullptr;
  // Topology may change only at the top, where the root orders all the remaining faces by error;
  // a lower stage's topology changes would reach into finer cuts.
  build.coarse_topology = build.coarse_topology && stage.root;
  const std::size_t target = stage.root ? options_.build.min_triangles : face_count / kStageReduction;
  MTLOD_TRY(BlockOutput result, simplify_block(std::move(block), target, build));
  block = BlockInput{};
  positions_->release();
  stage.complex_vertices = result.complex_vertices;
  stage.topology_collapses = result.topology_collapses;
  stage.topology_error = result.topology_error;
  stage.stacking_collapses = result.stacking_collapses;
  stage.stacking_error = result.stacking_error;

  MTLOD_RETURN_IF_ERROR(write_collapses(s, result, vertices));
  MTLOD_RETURN_IF_ERROR(write_owned(s, global, vertices, result));
  MTLOD_RETURN_IF_ERROR(write_creators(s, face_count, origin, result));
  // What remains, for the parent (the root's remains are the MT's root mesh; their creators stay
  // pending, which means the root).
  if (!stage.root) return write_remains(s, face_count, global, origin, result);
  stage.remaining = std::uint32_t(result.remaining.size());
  return Ok{};
}

Status LargeBuilder::simplify() {
  plan_stages();
  std::size_t done = 0;
  std::uint64_t alive = faces_;  // faces of the model's current mesh
  for (const std::vector<std::uint32_t>& level : levels_) {
    if (alive <= stats_->block_triangles)
      for (const std::uint32_t s : level) stages_[s].deferred = !stages_[s].root;
    // Side by side when there are several stages and a runner; a lone stage uses the runner inside.
    const bool side_by_side = options_.build.parallel_for != nullptr && level.size() > 1;
    if (!side_by_side) {
      for (const std::uint32_t s : level) {
        MTLOD_RETURN_IF_ERROR(run_stage(s, options_.build.parallel_for != nullptr));
        positions_->release();
        progress("simplifying", double(++done) / double(stages_.size()));
      }
    } else {
      struct Context {
        LargeBuilder* self;
        const std::vector<std::uint32_t>* level;
        std::vector<Status> results;
      } context{this, &level, std::vector<Status>(level.size(), Ok{})};
      options_.build.parallel_for(
          options_.build.parallel_user, level.size(),
          [](void* opaque, std::size_t i) {
            auto* c = static_cast<Context*>(opaque);
            c->results[i] = c->self->run_stage((*c->level)[i], false);
          },
          &context);
      for (Status& result : context.results) MTLOD_RETURN_IF_ERROR(std::move(result));
      positions_->release();
      done += level.size();
      progress("simplifying", double(done) / double(stages_.size()));
    }
    for (const std::uint32_t s : level) alive -= stages_[s].input_faces - stages_[s].remaining;
    note_temp();
  }
  return Ok{};
}

Status LargeBuilder::number_collapses(Assembly& a) {
  // Collapses in sequence order: stage by stage, each in its own order.
  a.collapse_base.assign(stages_.size() + 1, 0);
  for (std::size_t s = 0; s < stages_.size(); ++s)
    a.collapse_base[s + 1] = a.collapse_base[s] + stages_[s].collapses;
  const std::uint64_t k = a.collapse_base.back();
  for (const Stage& s : stages_) a.triangles += s.owned;
  if (k + 1 >= model::kNoNode || a.triangles >= model::kNoFace)
    return make_error(ErrorCode::kLimitExceeded,
                      fmt::format("{}: the MT's {} nodes and {} triangles exceed 32-bit ids", input_.string(),
                                  k + 1, a.triangles));
  a.node_count = std::uint32_t(k + 1);
  std::vector<std::uint32_t> collapse_u(k);
  std::vector<float> collapse_error(k);
  for (std::size_t s = 0; s < stages_.size(); ++s) {
    MTLOD_TRY(const auto records, read_array<std::uint32_t>(stage_file(std::uint32_t(s), "col")));
    for (std::size_t c = 0; c < stages_[s].collapses; ++c) {
      collapse_u[a.collapse_base[s] + c] = records[2 * c];
      std::memcpy(&collapse_error[a.collapse_base[s] + c], &records[2 * c + 1], 4);
    }
  }
  a.node_of = number_nodes(collapse_error);

  // Vertex ids as build_mt gives them: the root mesh's vertices by input id, then node n's split
  // vertex as R + n − 1, then the vertices no triangle uses.
  a.vertex_id.assign(vertex_count_, model::kNoVertex);
  a.node_vertex.assign(a.node_count, model::kNoVertex);
  a.node_error.assign(a.node_count, 0.0f);
  {
    for (const std::uint32_t u : collapse_u) a.vertex_id[u] = 0;  // split: numbered below
    std::uint32_t next = 0;
    for (std::uint64_t v = 0; v < vertex_count_; ++v)
      if (leaf_lo_[v] != model::kNoVertex && a.vertex_id[v] == model::kNoVertex) a.vertex_id[v] = next++;
    a.root_vertices = next;
    for (std::uint64_t c = 0; c < k; ++c) {
      a.vertex_id[collapse_u[c]] = a.root_vertices + a.node_of[c] - 1;
      a.node_vertex[a.node_of[c]] = a.vertex_id[collapse_u[c]];
      a.node_error[a.node_of[c]] = collapse_error[c];
    }
    // Vertices no kept triangle uses are left out of the file, as clean_mesh leaves them out.
    a.used_vertices = next + std::uint32_t(k);
  }
  for (const float e : a.node_error) stats_->max_error = std::max(stats_->max_error, e);
  if (options_.vertex_ids) *options_.vertex_ids = a.vertex_id;
  std::vector<std::uint32_t>().swap(collapse_u);
  std::vector<float>().swap(collapse_error);
  std::vector<std::uint32_t>().swap(leaf_hi_);
  std::vector<std::uint32_t>().swap(leaf_lo_);
  return Ok{};
}

Result<std::vector<std::uint32_t>> LargeBuilder::load_creators(const Assembly& a, std::uint32_t s) const {
  auto node_of_ref = [&](std::uint64_t ref) -> std::uint32_t {
    return ref == kPending ? 0u : a.node_of[a.collapse_base[ref_stage(ref)] + ref_index(ref) - 1];
  };
  MTLOD_TRY(const auto refs, read_array<std::uint64_t>(stage_file(s, "cre")));
  MTLOD_TRY(const auto updates, read_array<std::uint32_t>(stage_file(s, "upd"), true));
  std::vector<std::uint32_t> nodes(refs.size());
  for (std::size_t t = 0; t < refs.size(); ++t) nodes[t] = node_of_ref(refs[t]);
  for (std::size_t i = 0; i + 3 <= updates.size(); i += 3)
    nodes[updates[i]] = node_of_ref(ref_of(updates[i + 1], updates[i + 2]));
  return nodes;
}

// Calls each(collapse, sorted distinct parent nodes) for every collapse of stage s.
template <class Each>
void LargeBuilder::for_parents(Assembly& a, std::uint32_t s, const std::vector<std::uint32_t>& creators,
                               const std::vector<std::uint32_t>& made_by, const Each& each) const {
  const std::uint32_t inputs = stages_[s].inputs;
  for (std::size_t t = 0; t < made_by.size();) {
    const std::uint32_t tag = made_by[t];
    a.parents.clear();
    for (; t < made_by.size() && made_by[t] == tag; ++t) a.parents.push_back(creators[inputs + t]);
    std::sort(a.parents.begin(), a.parents.end());
    a.parents.erase(std::unique(a.parents.begin(), a.parents.end()), a.parents.end());
    each(a.node_of[a.collapse_base[s] + tag - 1], a.parents);
  }
}

Status LargeBuilder::count_nodes(Assembly& a) {
  // Creators of every owned triangle (with the updates later stages sent), counted by node; parents
  // of every node counted from the creators of the triangles its collapse made.
  a.triangle_offsets.assign(std::size_t{a.node_count} + 1, 0);
  a.parent_offsets.assign(std::size_t{a.node_count} + 1, 0);
  for (std::uint32_t s = 0; s < stages_.size(); ++s) {
    MTLOD_TRY(const auto creators, load_creators(a, s));
    for (const std::uint32_t n : creators) ++a.triangle_offsets[n + 1];
    MTLOD_TRY(const auto made_by, read_array<std::uint32_t>(stage_file(s, "madeby")));
    for_parents(a, s, creators, made_by, [&](std::uint32_t node, const std::vector<std::uint32_t>& list) {
      a.parent_offsets[node + 1] = std::uint32_t(list.size());
    });
    progress("assembling", 0.3 * double(s + 1) / double(stages_.size()));
  }
  for (std::size_t n = 0; n < a.node_count; ++n) {
    a.triangle_offsets[n + 1] += a.triangle_offsets[n];
    a.parent_offsets[n + 1] += a.parent_offsets[n];
  }
  a.counts.normals = normals_;
  a.counts.colors = colors_;
  a.counts.vertices = a.used_vertices;
  a.counts.nodes = a.node_count;
  a.counts.triangles = std::uint32_t(a.triangles);
  a.counts.root_triangles = a.triangle_offsets[1];
  a.counts.parents = a.parent_offsets[a.node_count];
  a.counts.root_vertices = a.root_vertices;
  a.layout = model::mt_layout(a.counts);
  stats_->nodes = a.node_count;
  stats_->mt_triangles = a.triangles;
  stats_->root_triangles = a.counts.root_triangles;
  return Ok{};
}

Status LargeBuilder::place_triangles(Assembly& a) {
  // Placement: each triangle's id in creator order, its corners rotated to follow the creator's
  // split vertex, into buckets of ids; parents straight into their array.
  a.node_parents.resize(a.counts.parents);
  a.root_first_corner.resize(a.counts.root_triangles);
  const std::uint64_t assembly = kFixedBytes + vertex_count_ * kAssemblyBytesPerVertex;
  a.bucket_triangles = std::clamp((limit_ > assembly ? limit_ - assembly : 0) / kBucketBytesPerTriangle,
                                  kMinBucketTriangles, kMaxBucketTriangles);
  a.buckets = std::max<std::uint64_t>(1, (a.triangles + a.bucket_triangles - 1) / a.bucket_triangles);
  std::vector<Writer> bucket_writers;
  for (std::uint64_t b = 0; b < a.buckets; ++b) {
    MTLOD_TRY(Writer w, Writer::open(file(fmt::format("bucket{}", b)), false, std::size_t{256} << 10));
    bucket_writers.push_back(std::move(w));
  }
  std::vector<std::uint32_t> next(a.triangle_offsets.begin(), a.triangle_offsets.end() - 1);
  // Placements gather per bucket and go out a few thousand at a time.
  constexpr std::size_t kPendingPlaced = 4096;
  std::vector<std::vector<Placed>> bucket_pending(a.buckets);
  for (auto& pending : bucket_pending) pending.reserve(kPendingPlaced);
  for (std::uint32_t s = 0; s < stages_.size(); ++s) {
    MTLOD_TRY(const auto creators, load_creators(a, s));
    MTLOD_TRY(const auto made_by, read_array<std::uint32_t>(stage_file(s, "madeby")));
    MTLOD_TRY(const auto own, read_array<std::uint32_t>(stage_file(s, "own")));
    const std::uint32_t inputs = stages_[s].inputs;
    for (std::size_t t = 0; t < creators.size(); ++t) {
      const std::uint32_t n = creators[t], id = next[n]++;
      const std::uint32_t tv[3] = {a.vertex_id[own[3 * t]], a.vertex_id[own[3 * t + 1]],
                                   a.vertex_id[own[3 * t + 2]]};
      int first = 0;
      if (n == 0) {
        a.root_first_corner[id] = tv[0];
      } else {
        first = tv[0] == a.node_vertex[n] ? 0 : (tv[1] == a.node_vertex[n] ? 1 : 2);
      }
      const std::uint32_t remover =
          t < inputs ? model::kNoNode : a.node_of[a.collapse_base[s] + made_by[t - inputs] - 1];
      std::vector<Placed>& pending = bucket_pending[id / a.bucket_triangles];
      pending.push_back(Placed{id, tv[(first + 1) % 3], tv[(first + 2) % 3], remover});
      if (pending.size() == kPendingPlaced) {
        MTLOD_RETURN_IF_ERROR(bucket_writers[id / a.bucket_triangles].write(pending));
        pending.clear();
      }
    }
    for_parents(a, s, creators, made_by, [&](std::uint32_t node, const std::vector<std::uint32_t>& list) {
      std::copy(list.begin(), list.end(), a.node_parents.begin() + a.parent_offsets[node]);
    });
    for (const char* kind : {"cre", "upd", "madeby", "own", "col"}) {
      std::error_code ec;
      fs::remove(stage_file(s, kind), ec);
    }
    progress("assembling", 0.3 + 0.4 * double(s + 1) / double(stages_.size()));
  }
  for (std::uint64_t b = 0; b < a.buckets; ++b) {
    MTLOD_RETURN_IF_ERROR(bucket_writers[b].write(bucket_pending[b]));
    MTLOD_RETURN_IF_ERROR(bucket_writers[b].close());
  }
  return Ok{};
}

Status LargeBuilder::write_vertices(Assembly& a, int fd, const fs::path& partial) {
  // Vertex arrays in the new order: gather from the input order, a chunk of new ids at a time.
  const std::uint32_t used_vertices = a.used_vertices;
  std::vector<std::uint32_t> old_of(used_vertices);
  for (std::uint32_t v = 0; v < vertex_count_; ++v)
    if (a.vertex_id[v] != model::kNoVertex) old_of[a.vertex_id[v]] = v;
  std::vector<std::uint32_t>().swap(a.vertex_id);
  auto permute = [&](const char* name, std::size_t bytes_per_vertex, std::uint64_t offset) -> Status {
    MTLOD_TRY(const MappedFile mapped, MappedFile::open(file(name)));
    const std::uint8_t* values = mapped.bytes();
    std::vector<std::uint8_t> out(bytes_per_vertex * std::min<std::uint64_t>(used_vertices, kChunkTriangles));
    for (std::uint64_t begin = 0; begin < used_vertices; begin += kChunkTriangles) {
      const std::uint64_t end = std::min<std::uint64_t>(used_vertices, begin + kChunkTriangles);
      for (std::uint64_t i = begin; i < end; ++i)
        std::memcpy(&out[(i - begin) * bytes_per_vertex], &values[old_of[i] * bytes_per_vertex],
                    bytes_per_vertex);
      MTLOD_RETURN_IF_ERROR(pwrite_all(fd, partial, out.data(), (end - begin) * bytes_per_vertex,
                                       offset + begin * bytes_per_vertex));
      mapped.release();
    }
    std::error_code ec;
    fs::remove(file(name), ec);
    return Ok{};
  };
  positions_.reset();
  MTLOD_RETURN_IF_ERROR(permute("positions", 12, a.layout.positions));
  if (normals_) MTLOD_RETURN_IF_ERROR(permute("normals", 12, a.layout.normals));
  if (colors_) MTLOD_RETURN_IF_ERROR(permute("colors", 3, a.layout.colors));
  return Ok{};
}

Status LargeBuilder::write_triangles(const Assembly& a, int fd, const fs::path& partial) {
  for (std::uint64_t b = 0; b < a.buckets; ++b) {
    MTLOD_TRY(const auto placed, read_array<Placed>(file(fmt::format("bucket{}", b))));
    const std::uint64_t first = b * a.bucket_triangles;
    const std::uint64_t count = std::min<std::uint64_t>(a.bucket_triangles, a.triangles - first);
    std::vector<std::uint32_t> corners(2 * count), removers(count);
    for (const Placed& p : placed) {
      corners[2 * (p.id - first)] = p.c1;
      corners[2 * (p.id - first) + 1] = p.c2;
      removers[p.id - first] = p.remover;
    }
    MTLOD_RETURN_IF_ERROR(put_array(fd, partial, corners, a.layout.triangle_corners + 8 * first));
    MTLOD_RETURN_IF_ERROR(put_array(fd, partial, removers, a.layout.triangle_remover + 4 * first));
    std::error_code ec;
    fs::remove(file(fmt::format("bucket{}", b)), ec);
    progress("writing", 0.2 + 0.5 * double(b + 1) / double(a.buckets));
  }
  return Ok{};
}

Status LargeBuilder::write_file(Assembly& a) {
  // The file: every array at its offset, then the checksum over all of it.
  const fs::path partial = output_.string() + ".partial";
  const int fd = ::open(partial.string().c_str(), O_RDWR | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) return io_error(partial, "create");
  struct Closer {
    int fd;
    ~Closer() { ::close(fd); }
  } closer{fd};
  auto put = [&](const auto& values, std::uint64_t offset) { return put_array(fd, partial, values, offset); };
  // The node arrays first, so that their memory is free for the vertex arrays and the buckets.
  const model::MtLayout& layout = a.layout;
  MTLOD_RETURN_IF_ERROR(put(a.node_vertex, layout.node_vertex));
  MTLOD_RETURN_IF_ERROR(put(a.node_error, layout.node_error));
  MTLOD_RETURN_IF_ERROR(put(a.triangle_offsets, layout.node_triangle_offsets));
  MTLOD_RETURN_IF_ERROR(put(a.parent_offsets, layout.node_parent_offsets));
  MTLOD_RETURN_IF_ERROR(put(a.node_parents, layout.node_parents));
  MTLOD_RETURN_IF_ERROR(put(a.root_first_corner, layout.root_first_corner));
  for (auto* array :
       {&a.node_vertex, &a.triangle_offsets, &a.parent_offsets, &a.node_parents, &a.root_first_corner})
    std::vector<std::uint32_t>().swap(*array);
  std::vector<float>().swap(a.node_error);
  std::vector<std::uint32_t>().swap(a.node_of);
  MTLOD_RETURN_IF_ERROR(write_vertices(a, fd, partial));
  progress("writing", 0.2);
  MTLOD_RETURN_IF_ERROR(write_triangles(a, fd, partial));
  {
    // The header and the block table last: each block's checksum reads its slices back.
    progress("writing", 0.7);
    auto seal = model::seal_mt(a.counts, [&](std::uint64_t offset, std::span<std::uint8_t> out) -> Status {
      const ssize_t n = ::pread(fd, out.data(), out.size(), off_t(offset));
      if (n != ssize_t(out.size())) return io_error(partial, "read back");
      return Ok{};
    });
    if (!seal.ok()) return seal.take_error();
    MTLOD_RETURN_IF_ERROR(put(seal->block_table, layout.block_table));
    MTLOD_RETURN_IF_ERROR(put(seal->header, 0));
  }
  std::error_code ec;
  fs::rename(partial, output_, ec);
  if (ec)
    return make_error(ErrorCode::kIoError,
                      fmt::format("{}: cannot rename into place: {}", output_.string(), ec.message()));
  stats_->file_bytes = layout.end;
  return Ok{};
}

Status LargeBuilder::assemble() {
  Assembly a;
  MTLOD_RETURN_IF_ERROR(number_collapses(a));
  MTLOD_RETURN_IF_ERROR(count_nodes(a));
  MTLOD_RETURN_IF_ERROR(place_triangles(a));
  note_temp();
  return write_file(a);
}

Status LargeBuilder::run(LargeBuildStats& stats) {
  stats_ = &stats;
  limit_ = options_.memory_limit ? options_.memory_limit : io::default_memory_limit();
  MTLOD_TRY(io::PlyReader reader, io::PlyReader::open(input_));
  MTLOD_RETURN_IF_ERROR(read_vertices(reader));
  stats.vertices = vertex_count_;
  MTLOD_RETURN_IF_ERROR(read_faces(reader));
  MTLOD_RETURN_IF_ERROR(check_normals());
  MTLOD_RETURN_IF_ERROR(choose_leaves());
  MTLOD_RETURN_IF_ERROR(distribute());
  MTLOD_RETURN_IF_ERROR(simplify());
  MTLOD_RETURN_IF_ERROR(finish_normals());
  for (const Stage& s : stages_) {
    stats.dropped_duplicate += s.duplicates;
    stats.complex_vertices += s.complex_vertices;
    stats.topology_collapses += s.topology_collapses;
    stats.topology_error = std::min(stats.topology_error, s.topology_error);
    stats.stacking_collapses += s.stacking_collapses;
    stats.stacking_error = std::min(stats.stacking_error, s.stacking_error);
  }
  return assemble();
}

}  // namespace

Status build_mt_file(const fs::path& input, const fs::path& output, const LargeBuildOptions& options,
                     LargeBuildStats* stats) {
  LargeBuildStats local;
  LargeBuildStats& out = stats ? *stats : local;
  out = LargeBuildStats{};
  fs::path parent = options.temp_dir;
  if (parent.empty()) parent = output.has_parent_path() ? output.parent_path() : fs::path(".");
  MTLOD_TRY(TempDir temp, TempDir::create(parent));
  LargeBuilder builder(input, output, options, temp);
  return builder.run(out);
}

}  // namespace mtlod::core::build
