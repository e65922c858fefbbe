// Streaming PLY (see ply_stream.hpp). The reader parses the header itself, then decodes records
// straight out of one block buffer refilled by large reads, so its memory is the buffer's size
// whatever the file's. The layouts real files use (binary float xyz, faces as a uchar or int list of
// 32-bit indices) take copy-only loops; everything else goes through a per-property decoder that
// handles any scalar type, byte order, list and ASCII token.
#include "core/io/ply_stream.hpp"

#include <algorithm>
#include <bit>
#include <cassert>
#include <charconv>
#include <cmath>
#include <cstring>
#include <optional>
#include <string_view>
#include <system_error>
#include <vector>

#include "fmt/format.h"

namespace mtlod::core::io {
namespace {

// Large enough that a read costs little per byte, small enough to stay out of the way of the
// builder's own memory; every record and ASCII token must fit in it.
constexpr std::size_t kReadBufferBytes = std::size_t{4} << 20;
constexpr std::size_t kWriteBufferBytes = std::size_t{1} << 20;
constexpr std::size_t kMaxHeaderBytes = std::size_t{1} << 20;
constexpr std::size_t kMaxTokenBytes = 4096;  // no number is longer; a longer token is garbage

enum class Type : std::uint8_t { kInt8, kUint8, kInt16, kUint16, kInt32, kUint32, kFloat32, kFloat64 };

struct TypeName {
  std::string_view name;
  Type type;
};
constexpr TypeName kTypeNames[] = {
    {"char", Type::kInt8},       {"int8", Type::kInt8},       {"uchar", Type::kUint8},
    {"uint8", Type::kUint8},     {"short", Type::kInt16},     {"int16", Type::kInt16},
    {"ushort", Type::kUint16},   {"uint16", Type::kUint16},   {"int", Type::kInt32},
    {"int32", Type::kInt32},     {"uint", Type::kUint32},     {"uint32", Type::kUint32},
    {"float", Type::kFloat32},   {"float32", Type::kFloat32}, {"double", Type::kFloat64},
    {"float64", Type::kFloat64},
};
constexpr std::size_t kTypeBytes[] = {1, 1, 2, 2, 4, 4, 4, 8};

std::size_t type_bytes(Type t) {
  return kTypeBytes[static_cast<int>(t)];
}
bool is_integer(Type t) {
  return t < Type::kFloat32;
}

std::optional<Type> parse_type(std::string_view name) {
  for (const TypeName& t : kTypeNames) {
    if (t.name == name) return t.type;
  }
  return std::nullopt;
}

// What the reader does with a property. The colour channels follow kRed in order, as do y, z after
// kX and the normal's components after kNx.
enum class Role : std::uint8_t { kSkip, kX, kY, kZ, kNx, kNy, kNz, kRed, kGreen, kBlue, kIndices };
constexpr int kRoleCount = 11;

struct Property {
  std::string name;
  Type type = Type::kUint8;        // a scalar's type, or a list's entry type
  Type count_type = Type::kUint8;  // lists only
  bool list = false;
  Role role = Role::kSkip;
  std::size_t offset = 0;  // in a binary record without lists
};

struct Element {
  std::string name;
  std::uint64_t count = 0;
  std::vector<Property> properties;
  std::uint64_t fixed_bytes = 0;  // per binary record, lists counting their length field only
  bool has_lists = false;
};

template <class T>
T load(const unsigned char* p, bool swap) {
  T v;
  std::memcpy(&v, p, sizeof v);
  if (swap) {
    unsigned char bytes[sizeof v];
    std::memcpy(bytes, &v, sizeof v);
    std::reverse(bytes, bytes + sizeof v);
    std::memcpy(&v, bytes, sizeof v);
  }
  return v;
}

// A scalar of type t as R. Every PLY scalar converts exactly to double, so positions and normals of
// any type round once, to float, as a direct conversion would; list counts and indices are
// integers (the header admits no other list types).
template <class R>
R load_as(const unsigned char* p, Type t, bool swap) {
  switch (t) {
    case Type::kInt8:
      return R(load<std::int8_t>(p, swap));
    case Type::kUint8:
      return R(load<std::uint8_t>(p, swap));
    case Type::kInt16:
      return R(load<std::int16_t>(p, swap));
    case Type::kUint16:
      return R(load<std::uint16_t>(p, swap));
    case Type::kInt32:
      return R(load<std::int32_t>(p, swap));
    case Type::kUint32:
      return R(load<std::uint32_t>(p, swap));
    case Type::kFloat32:
      return R(load<float>(p, swap));
    case Type::kFloat64:
      return R(load<double>(p, swap));
  }
  return R(0);
}

double load_number(const unsigned char* p, Type t, bool swap) {
  return load_as<double>(p, t, swap);
}

std::int64_t load_integer(const unsigned char* p, Type t, bool swap) {
  assert(t != Type::kFloat32 && t != Type::kFloat64 && "the header admits integer list types only");
  return load_as<std::int64_t>(p, t, swap);
}

// Colours as load_mesh stores them: floats in [0, 1] scaled (in the file's precision, as OpenMesh's
// importer does for float), integers clamped, which keeps bytes as they are.
std::uint8_t color_byte(double v, Type t) {
  if (t == Type::kFloat32) {
    const float x = static_cast<float>(v);
    return static_cast<std::uint8_t>(
        std::lround(std::clamp(std::isfinite(x) ? x : 0.0f, 0.0f, 1.0f) * 255.0f));
  }
  if (t == Type::kFloat64) {
    return static_cast<std::uint8_t>(std::lround(std::clamp(std::isfinite(v) ? v : 0.0, 0.0, 1.0) * 255.0));
  }
  return static_cast<std::uint8_t>(std::clamp(v, 0.0, 255.0));
}

bool parse_integer(std::string_view token, std::int64_t& out) {
  if (token.size() > 1 && token.front() == '+') token.remove_prefix(1);
  const auto [end, ec] = std::from_chars(token.data(), token.data() + token.size(), out);
  return ec == std::errc() && end == token.data() + token.size();
}

// An ASCII value of the declared type. from_chars refuses values beyond a float's range (1e-50 as
// float); strtod gives them as the nearest representable value, which is what a writer meant.
bool parse_number(std::string_view token, Type type, double& out) {
  if (is_integer(type)) {
    std::int64_t v = 0;
    if (!parse_integer(token, v)) return false;
    out = static_cast<double>(v);
    return true;
  }
  if (token.size() > 1 && token.front() == '+') token.remove_prefix(1);
  const char* first = token.data();
  const char* last = first + token.size();
  std::from_chars_result parsed;
  if (type == Type::kFloat32) {
    float v = 0;
    parsed = std::from_chars(first, last, v);
    out = v;
  } else {
    parsed = std::from_chars(first, last, out);
  }
  if (parsed.ptr != last) return false;
  if (parsed.ec == std::errc::result_out_of_range) {
    const double v = std::strtod(std::string(token).c_str(), nullptr);
    out = type == Type::kFloat32 ? static_cast<double>(static_cast<float>(v)) : v;
    return true;
  }
  return parsed.ec == std::errc();
}

std::vector<std::string_view> split_words(std::string_view line) {
  std::vector<std::string_view> words;
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t')) ++i;
    const std::size_t start = i;
    while (i < line.size() && line[i] != ' ' && line[i] != '\t') ++i;
    if (i > start) words.push_back(line.substr(start, i - start));
  }
  return words;
}

Role vertex_role(std::string_view name) {
  if (name == "x") return Role::kX;
  if (name == "y") return Role::kY;
  if (name == "z") return Role::kZ;
  if (name == "nx") return Role::kNx;
  if (name == "ny") return Role::kNy;
  if (name == "nz") return Role::kNz;
  if (name == "red" || name == "r" || name == "diffuse_red") return Role::kRed;
  if (name == "green" || name == "g" || name == "diffuse_green") return Role::kGreen;
  if (name == "blue" || name == "b" || name == "diffuse_blue") return Role::kBlue;
  return Role::kSkip;
}

template <class T>
void store_le(unsigned char* out, T v) {
  static_assert(std::endian::native == std::endian::little || std::endian::native == std::endian::big);
  std::memcpy(out, &v, sizeof v);
  if constexpr (std::endian::native == std::endian::big) std::reverse(out, out + sizeof v);
}

}  // namespace

// ---------------------------------------------------------------------------------------------------
// PlyReader

struct PlyReader::State {
  static constexpr std::size_t kNone = SIZE_MAX;

  std::string name;
  std::FILE* file = nullptr;
  std::uint64_t file_size = 0;
  std::uint64_t file_offset = 0;  // of the byte after the buffer's last
  std::unique_ptr<unsigned char[]> buffer;
  std::size_t pos = 0;  // next unread byte
  std::size_t end = 0;  // after the last byte read
  bool eof = false;
  bool io_error = false;

  PlyHeader header;
  bool ascii = false;
  bool swap = false;  // binary in the other byte order than the machine's
  std::vector<Element> elements;
  std::size_t vertex_element = kNone;
  std::size_t face_element = kNone;
  // Where each vertex role sits in a fixed-size binary record, and its type.
  std::size_t role_offset[kRoleCount] = {};
  Type role_type[kRoleCount] = {};
  bool xyz_packed = false;             // x, y, z adjacent float32 in the machine's order: one memcpy
  bool normals_packed = false;         // likewise nx, ny, nz
  bool colors_packed = false;          // red, green, blue adjacent uchar
  int fast_face_count_bytes = 0;       // faces are only a list of 32-bit indices with this length size
  std::uint32_t fast_index_bound = 0;  // indices below this are valid (int32 indices: also >= 0)

  std::size_t element = 0;   // being read
  std::uint64_t record = 0;  // next record of that element
  std::vector<std::uint32_t> corners;
  std::vector<std::uint32_t> pending;  // a face read but not yet returned, for lack of room
  std::uint64_t polygons_triangulated = 0;
  std::uint64_t faces_dropped = 0;
  std::optional<Error> failure;  // the first error, returned again by every later call

  ~State() {
    if (file) std::fclose(file);
  }

  // Moves the unread bytes to the front and appends what the file has next; returns the count.
  std::size_t refill() {
    if (eof || io_error) return 0;
    const std::size_t keep = end - pos;
    if (pos > 0) {
      std::memmove(buffer.get(), buffer.get() + pos, keep);
      pos = 0;
      end = keep;
    }
    const std::size_t wanted = kReadBufferBytes - end;
    const std::size_t got = std::fread(buffer.get() + end, 1, wanted, file);
    end += got;
    file_offset += got;
    if (got < wanted) {
      if (std::ferror(file))
        io_error = true;
      else
        eof = true;
    }
    return got;
  }

  bool ensure(std::size_t bytes) {
    assert(bytes <= kReadBufferBytes);
    while (end - pos < bytes) {
      if (refill() == 0) return false;
    }
    return true;
  }

  // Skips bytes of a binary body, seeking over what is not in the buffer. False when the file
  // does not have them.
  bool skip_bytes(std::uint64_t bytes) {
    const std::size_t have = end - pos;
    if (bytes <= have) {
      pos += static_cast<std::size_t>(bytes);
      return true;
    }
    bytes -= have;
    pos = end = 0;
    if (bytes > file_size - std::min(file_size, file_offset)) return false;
    if (bytes >= kReadBufferBytes && !eof && !io_error &&
        fseeko(file, static_cast<off_t>(bytes), SEEK_CUR) == 0) {
      file_offset += bytes;
      return true;
    }
    while (bytes > 0) {
      if (refill() == 0) return false;
      const std::size_t take = static_cast<std::size_t>(std::min<std::uint64_t>(bytes, end - pos));
      pos += take;
      bytes -= take;
    }
    return true;
  }

  enum class Token { kOk, kEnd, kTooLong };

  // The next whitespace-separated ASCII token; PLY records may span or share lines.
  Token next_token(std::string_view& token) {
    const unsigned char* b = buffer.get();
    for (;;) {
      while (pos < end && b[pos] <= ' ') ++pos;
      if (pos < end) break;
      if (refill() == 0) return Token::kEnd;
    }
    std::size_t stop = pos;
    for (;;) {
      while (stop < end && b[stop] > ' ') ++stop;
      if (stop < end) break;
      const std::size_t length = stop - pos;
      if (length > kMaxTokenBytes) return Token::kTooLong;
      if (refill() == 0) break;  // the token ends with the file
      stop = pos + length;
    }
    if (stop - pos > kMaxTokenBytes) return Token::kTooLong;
    token = std::string_view(reinterpret_cast<const char*>(b) + pos, stop - pos);
    pos = stop;
    return Token::kOk;
  }

  std::string record_label(std::size_t e, std::uint64_t k) const {
    if (e == vertex_element) return fmt::format("vertex {}", k);
    if (e == face_element) return fmt::format("face {}", k);
    return fmt::format("element '{}' record {}", elements[e].name, k);
  }
  std::string where() const { return record_label(element, record); }

  Error truncated() const {
    if (io_error) {
      return make_error(ErrorCode::kIoError, fmt::format("{}: read error in {}", name, where()));
    }
    return make_error(ErrorCode::kCorrupt,
                      fmt::format("{}: truncated: the file ends inside {}", name, where()));
  }
  Error token_error(Token t) const {
    if (t == Token::kEnd) return truncated();
    return make_error(ErrorCode::kCorrupt, fmt::format("{}: {}: a value longer than {} characters", name,
                                                       where(), kMaxTokenBytes));
  }
  Error bad_value(std::string_view token, Type t) const {
    if (io_error) return truncated();
    const std::string_view shown = token.substr(0, 40);
    return make_error(
        ErrorCode::kCorrupt,
        fmt::format("{}: {}: '{}{}' is not a valid {} value", name, where(), shown,
                    shown.size() < token.size() ? "..." : "", kTypeNames[2 * static_cast<int>(t)].name));
  }

  // One scalar of type t, from either body encoding.
  Status read_number(Type t, double& out) {
    if (!ascii) {
      if (!ensure(type_bytes(t))) return truncated();
      out = load_number(buffer.get() + pos, t, swap);
      pos += type_bytes(t);
      return Ok{};
    }
    std::string_view token;
    if (const Token got = next_token(token); got != Token::kOk) return token_error(got);
    if (!parse_number(token, t, out)) return bad_value(token, t);
    return Ok{};
  }

  Status read_integer(Type t, std::int64_t& out) {
    if (!ascii) {
      if (!ensure(type_bytes(t))) return truncated();
      out = load_integer(buffer.get() + pos, t, swap);
      pos += type_bytes(t);
      return Ok{};
    }
    std::string_view token;
    if (const Token got = next_token(token); got != Token::kOk) return token_error(got);
    if (!parse_integer(token, out)) return bad_value(token, t);
    return Ok{};
  }

  Status read_list_length(Type t, std::uint64_t& out) {
    std::int64_t length = 0;
    MTLOD_RETURN_IF_ERROR(read_integer(t, length));
    if (length < 0) {
      return make_error(ErrorCode::kCorrupt, fmt::format("{}: {}: list length {}", name, where(), length));
    }
    out = static_cast<std::uint64_t>(length);
    return Ok{};
  }

  Status skip_values(Type t, std::uint64_t count) {
    if (!ascii) {
      // count comes from an at most 32-bit length field: the product cannot overflow.
      if (!skip_bytes(count * type_bytes(t))) return truncated();
      return Ok{};
    }
    std::string_view token;
    for (std::uint64_t i = 0; i < count; ++i) {
      if (const Token got = next_token(token); got != Token::kOk) return token_error(got);
    }
    return Ok{};
  }

  Status skip_property(const Property& p) {
    std::uint64_t count = 1;
    if (p.list) MTLOD_RETURN_IF_ERROR(read_list_length(p.count_type, count));
    return skip_values(p.type, count);
  }

  // Skips the next records of the current element.
  Status skip_records(std::uint64_t n) {
    const Element& e = elements[element];
    if (n == 0 || e.properties.empty()) {
      record += n;
      return Ok{};
    }
    if (!ascii && !e.has_lists) {
      // n * fixed_bytes was checked against the file size at open.
      const std::uint64_t available = (end - pos) + (file_size - std::min(file_size, file_offset));
      if (available < n * e.fixed_bytes) {
        record += available / e.fixed_bytes;
        return truncated();
      }
      if (!skip_bytes(n * e.fixed_bytes)) return truncated();  // the file shrank since open
      record += n;
      return Ok{};
    }
    for (; n > 0; --n, ++record) {
      for (const Property& p : e.properties) MTLOD_RETURN_IF_ERROR(skip_property(p));
    }
    return Ok{};
  }

  Status skip_to(std::size_t target) {
    while (element < target) {
      MTLOD_RETURN_IF_ERROR(skip_records(elements[element].count - record));
      ++element;
      record = 0;
    }
    return Ok{};
  }

  Error non_finite(const float* p) const {
    return make_error(ErrorCode::kCorrupt, fmt::format("{}: {} has a non-finite coordinate ({}, {}, {})",
                                                       name, where(), p[0], p[1], p[2]));
  }

  // Vertices as fixed-size binary records, decoded in place from the buffer.
  Status read_fixed_vertices(std::size_t n, float* positions, float* normals, std::uint8_t* colors) {
    const std::size_t bytes = static_cast<std::size_t>(elements[vertex_element].fixed_bytes);
    const std::size_t* off = role_offset;
    const Type* type = role_type;
    std::size_t done = 0;
    while (done < n) {
      if (end - pos < bytes && !ensure(bytes)) return truncated();
      const std::size_t take = std::min(n - done, (end - pos) / bytes);
      const unsigned char* r = buffer.get() + pos;
      for (std::size_t i = 0; i < take; ++i, r += bytes) {
        const std::size_t v = done + i;
        float* p = positions + 3 * v;
        if (xyz_packed) {
          std::memcpy(p, r + off[int(Role::kX)], 12);
        } else {
          for (int c = 0; c < 3; ++c) {
            p[c] = static_cast<float>(load_number(r + off[int(Role::kX) + c], type[int(Role::kX) + c], swap));
          }
        }
        if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2])) {
          record += i;
          return non_finite(p);
        }
        if (normals && normals_packed) {
          std::memcpy(normals + 3 * v, r + off[int(Role::kNx)], 12);
        } else if (normals) {
          for (int c = 0; c < 3; ++c) {
            normals[3 * v + c] =
                static_cast<float>(load_number(r + off[int(Role::kNx) + c], type[int(Role::kNx) + c], swap));
          }
        }
        if (colors && colors_packed) {
          std::memcpy(colors + 3 * v, r + off[int(Role::kRed)], 3);
        } else if (colors) {
          for (int c = 0; c < 3; ++c) {
            const Type t = type[int(Role::kRed) + c];
            colors[3 * v + c] = color_byte(load_number(r + off[int(Role::kRed) + c], t, swap), t);
          }
        }
      }
      pos += take * bytes;
      record += take;
      done += take;
    }
    return Ok{};
  }

  // One vertex property by property: ASCII, or binary records holding lists.
  Status read_vertex(float* position, float* normal, std::uint8_t* color) {
    float p[3] = {}, n[3] = {};
    std::uint8_t c[3] = {};
    for (const Property& prop : elements[vertex_element].properties) {
      if (prop.list || prop.role == Role::kSkip) {
        MTLOD_RETURN_IF_ERROR(skip_property(prop));
        continue;
      }
      double v = 0;
      MTLOD_RETURN_IF_ERROR(read_number(prop.type, v));
      const int role = static_cast<int>(prop.role);
      if (role <= int(Role::kZ))
        p[role - int(Role::kX)] = static_cast<float>(v);
      else if (role <= int(Role::kNz))
        n[role - int(Role::kNx)] = static_cast<float>(v);
      else
        c[role - int(Role::kRed)] = color_byte(v, prop.type);
    }
    if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2])) return non_finite(p);
    std::copy_n(p, 3, position);
    if (normal) std::copy_n(n, 3, normal);
    if (color) std::copy_n(c, 3, color);
    return Ok{};
  }

  Result<std::size_t> read_vertices(std::span<float> positions, std::span<float> normals,
                                    std::span<std::uint8_t> colors) {
    assert(positions.size() >= 3);
    if (element > vertex_element) return std::size_t{0};
    MTLOD_RETURN_IF_ERROR(skip_to(vertex_element));
    std::size_t n = positions.size() / 3;
    float* normal_out = nullptr;
    std::uint8_t* color_out = nullptr;
    if (header.has_normals && !normals.empty()) {
      assert(normals.size() >= positions.size());
      n = std::min(n, normals.size() / 3);
      normal_out = normals.data();
    }
    if (header.has_colors && !colors.empty()) {
      assert(colors.size() >= positions.size());
      n = std::min(n, colors.size() / 3);
      color_out = colors.data();
    }
    n = static_cast<std::size_t>(std::min<std::uint64_t>(n, header.vertex_count - record));
    if (!ascii && !elements[vertex_element].has_lists) {
      MTLOD_RETURN_IF_ERROR(read_fixed_vertices(n, positions.data(), normal_out, color_out));
      return n;
    }
    for (std::size_t v = 0; v < n; ++v, ++record) {
      MTLOD_RETURN_IF_ERROR(read_vertex(&positions[3 * v], normal_out ? normal_out + 3 * v : nullptr,
                                        color_out ? color_out + 3 * v : nullptr));
    }
    return n;
  }

  // Faces that are exactly "list <CountT> <32-bit> vertex_indices" and triangles, copied from the
  // buffer; stops at anything else (a polygon, a bad index, the buffer's end) for read_face.
  template <class CountT>
  std::size_t copy_binary_triangles(std::uint32_t* out, std::size_t room) {
    constexpr std::size_t kBytes = sizeof(CountT) + 12;
    const std::size_t n = static_cast<std::size_t>(std::min<std::uint64_t>(room, header.face_count - record));
    const unsigned char* p = buffer.get() + pos;
    const std::size_t whole = (end - pos) / kBytes;
    const std::uint32_t bound = fast_index_bound;
    std::size_t done = 0;
    for (const std::size_t stop = std::min(n, whole); done < stop; ++done, p += kBytes, out += 3) {
      CountT corners;
      std::memcpy(&corners, p, sizeof corners);
      std::uint32_t v[3];
      std::memcpy(v, p + sizeof corners, 12);
      if (corners != 3 || v[0] >= bound || v[1] >= bound || v[2] >= bound) break;
      std::memcpy(out, v, 12);
    }
    pos += done * kBytes;
    record += done;
    return done;
  }

  // The next face's corners (property by property), checked against the vertex count.
  Status read_face(std::size_t room_triangles) {
    corners.clear();
    bool seen = false;
    for (const Property& prop : elements[face_element].properties) {
      if (prop.role != Role::kIndices || seen) {
        MTLOD_RETURN_IF_ERROR(skip_property(prop));
        continue;
      }
      seen = true;
      std::uint64_t count = 0;
      MTLOD_RETURN_IF_ERROR(read_list_length(prop.count_type, count));
      if (count >= 3 && count - 2 > room_triangles) {
        return make_error(ErrorCode::kLimitExceeded,
                          fmt::format("{}: {} has {} corners: its {} triangles do not fit in the room for {}",
                                      name, where(), count, count - 2, room_triangles));
      }
      corners.resize(static_cast<std::size_t>(count));
      for (std::uint32_t& corner : corners) {
        std::int64_t v = 0;
        MTLOD_RETURN_IF_ERROR(read_integer(prop.type, v));
        if (v < 0 || static_cast<std::uint64_t>(v) >= header.vertex_count) {
          return make_error(ErrorCode::kCorrupt,
                            fmt::format("{}: {} refers to vertex {}, but the file has {} vertices", name,
                                        where(), v, header.vertex_count));
        }
        corner = static_cast<std::uint32_t>(v);
      }
    }
    return Ok{};
  }

  static std::size_t emit_fan(const std::vector<std::uint32_t>& face, std::uint32_t* out) {
    for (std::size_t k = 1; k + 1 < face.size(); ++k, out += 3) {
      out[0] = face[0];
      out[1] = face[k];
      out[2] = face[k + 1];
    }
    return face.size() - 2;
  }

  Result<std::size_t> read_triangles(std::span<std::uint32_t> triangles) {
    assert(triangles.size() >= 3);
    if (face_element == kNone || element > face_element) return std::size_t{0};
    MTLOD_RETURN_IF_ERROR(skip_to(face_element));
    const std::size_t capacity = triangles.size() / 3;
    std::uint32_t* out = triangles.data();
    std::size_t written = 0;
    if (!pending.empty()) {
      if (pending.size() - 2 > capacity) {
        return make_error(ErrorCode::kInvalidArgument,
                          fmt::format("{}: the face before {} needs room for {} triangles, not {}", name,
                                      where(), pending.size() - 2, capacity));
      }
      written += emit_fan(pending, out);
      pending.clear();
    }
    while (written < capacity && record < header.face_count) {
      switch (fast_face_count_bytes) {
        case 1:
          written += copy_binary_triangles<std::uint8_t>(out + 3 * written, capacity - written);
          break;
        case 2:
          written += copy_binary_triangles<std::uint16_t>(out + 3 * written, capacity - written);
          break;
        case 4:
          written += copy_binary_triangles<std::uint32_t>(out + 3 * written, capacity - written);
          break;
        default:
          break;
      }
      if (written == capacity || record == header.face_count) break;
      MTLOD_RETURN_IF_ERROR(read_face(capacity));
      ++record;
      if (corners.size() < 3) {
        ++faces_dropped;
        continue;
      }
      if (corners.size() > 3) ++polygons_triangulated;
      if (corners.size() - 2 > capacity - written) {
        pending.swap(corners);
        break;
      }
      written += emit_fan(corners, out + 3 * written);
    }
    return written;
  }

  // Parses the header in the buffer's first bytes and sets up the decoding.
  Status parse_header() {
    refill();
    if (io_error) return make_error(ErrorCode::kIoError, fmt::format("{}: read error in the header", name));
    const std::string_view text(reinterpret_cast<const char*>(buffer.get()), std::min(end, kMaxHeaderBytes));
    if (text.empty()) return make_error(ErrorCode::kCorrupt, fmt::format("{}: empty file", name));
    if (!(text.starts_with("ply\n") || text.starts_with("ply\r\n"))) {
      return make_error(ErrorCode::kCorrupt,
                        fmt::format("{}: not a PLY file (it does not start with 'ply')", name));
    }
    auto corrupt = [&](std::string_view why, std::string_view line) {
      return make_error(ErrorCode::kCorrupt, fmt::format("{}: {} in header line '{}'", name, why, line));
    };
    auto unsupported = [&](std::string_view why, std::string_view line) {
      return make_error(ErrorCode::kUnsupported, fmt::format("{}: {} in header line '{}'", name, why, line));
    };
    std::string_view format;
    std::size_t line_start = text.find('\n') + 1;
    for (;;) {
      const std::size_t newline = text.find('\n', line_start);
      if (newline == std::string_view::npos) {
        return make_error(ErrorCode::kCorrupt,
                          end < kMaxHeaderBytes ? fmt::format("{}: the header has no end_header line", name)
                                                : fmt::format("{}: no end_header line in the first {} bytes",
                                                              name, kMaxHeaderBytes));
      }
      std::string_view line = text.substr(line_start, newline - line_start);
      line_start = newline + 1;
      if (line.ends_with('\r')) line.remove_suffix(1);
      const std::vector<std::string_view> words = split_words(line);
      if (words.empty() || words[0] == "comment" || words[0] == "obj_info") continue;
      if (words[0] == "end_header") break;
      if (words[0] == "format") {
        if (words.size() != 3) return corrupt("bad format line", line);
        if (words[1] != "ascii" && words[1] != "binary_little_endian" && words[1] != "binary_big_endian") {
          return unsupported("unknown format", line);
        }
        if (words[2] != "1.0") return unsupported("unknown PLY version", line);
        format = words[1];
      } else if (words[0] == "element") {
        Element e;
        if (words.size() != 3) return corrupt("bad element line", line);
        e.name = words[1];
        const auto [ptr, ec] = std::from_chars(words[2].data(), words[2].data() + words[2].size(), e.count);
        if (ec != std::errc() || ptr != words[2].data() + words[2].size())
          return corrupt("bad element count", line);
        elements.push_back(std::move(e));
      } else if (words[0] == "property") {
        if (elements.empty()) return corrupt("a property before any element", line);
        Property p;
        const bool list = words.size() == 5 && words[1] == "list";
        if (!list && words.size() != 3) return corrupt("bad property line", line);
        const auto type = parse_type(words[list ? 3 : 1]);
        if (!type) return unsupported("unknown property type", line);
        p.type = *type;
        if (list) {
          const auto count_type = parse_type(words[2]);
          if (!count_type) return unsupported("unknown property type", line);
          if (!is_integer(*count_type)) return unsupported("a list length that is not an integer type", line);
          p.count_type = *count_type;
          p.list = true;
        }
        p.name = words[list ? 4 : 2];
        elements.back().properties.push_back(std::move(p));
      } else {
        return corrupt("unknown keyword", line);
      }
    }
    header.header_bytes = line_start;
    pos = line_start;
    if (format.empty())
      return make_error(ErrorCode::kCorrupt, fmt::format("{}: the header has no format line", name));
    ascii = format == "ascii";
    header.binary = !ascii;
    swap = !ascii && (format == "binary_big_endian") != (std::endian::native == std::endian::big);
    MTLOD_RETURN_IF_ERROR(find_elements());
    return check_size();
  }

  Status find_elements() {
    for (std::size_t i = 0; i < elements.size(); ++i) {
      Element& e = elements[i];
      for (Property& p : e.properties) {
        if (p.list) e.has_lists = true;
        p.offset = static_cast<std::size_t>(e.fixed_bytes);
        e.fixed_bytes += type_bytes(p.list ? p.count_type : p.type);
      }
      if (e.name != "vertex" && e.name != "face") continue;
      std::size_t& slot = e.name == "vertex" ? vertex_element : face_element;
      if (slot != kNone) {
        return make_error(ErrorCode::kUnsupported,
                          fmt::format("{}: more than one '{}' element", name, e.name));
      }
      slot = i;
    }
    if (vertex_element == kNone) {
      return make_error(ErrorCode::kCorrupt, fmt::format("{}: the header declares no vertex element", name));
    }
    if (face_element != kNone && face_element < vertex_element) {
      return make_error(
          ErrorCode::kUnsupported,
          fmt::format("{}: the face element comes before the vertex element; reading in one pass "
                      "needs the vertices first",
                      name));
    }
    Element& vertices = elements[vertex_element];
    header.vertex_count = vertices.count;
    // The first property of each name counts; a partial normal or colour is skipped.
    Property* by_role[kRoleCount] = {};
    for (Property& p : vertices.properties) {
      const Role role = vertex_role(p.name);
      if (role == Role::kSkip || by_role[int(role)]) continue;
      if (p.list) {
        return make_error(ErrorCode::kUnsupported,
                          fmt::format("{}: vertex property '{}' is a list, not a number", name, p.name));
      }
      by_role[int(role)] = &p;
    }
    for (const char* axis : {"x", "y", "z"}) {
      if (!by_role[int(vertex_role(axis))]) {
        return make_error(ErrorCode::kUnsupported,
                          fmt::format("{}: the vertex element has no '{}' property", name, axis));
      }
    }
    header.has_normals = by_role[int(Role::kNx)] && by_role[int(Role::kNy)] && by_role[int(Role::kNz)];
    header.has_colors = by_role[int(Role::kRed)] && by_role[int(Role::kGreen)] && by_role[int(Role::kBlue)];
    for (int role = 1; role <= int(Role::kBlue); ++role) {
      Property* p = by_role[role];
      if (!p) continue;
      if ((role >= int(Role::kNx) && role <= int(Role::kNz) && !header.has_normals) ||
          (role >= int(Role::kRed) && !header.has_colors)) {
        continue;
      }
      p->role = static_cast<Role>(role);
      role_offset[role] = p->offset;
      role_type[role] = p->type;
    }
    auto packed = [&](Role first, Type t) {
      const int r = int(first);
      return !swap && role_type[r] == t && role_type[r + 1] == t && role_type[r + 2] == t &&
             role_offset[r + 1] == role_offset[r] + type_bytes(t) &&
             role_offset[r + 2] == role_offset[r] + 2 * type_bytes(t);
    };
    xyz_packed = packed(Role::kX, Type::kFloat32);
    normals_packed = header.has_normals && packed(Role::kNx, Type::kFloat32);
    colors_packed = header.has_colors && packed(Role::kRed, Type::kUint8);

    if (face_element == kNone) return Ok{};
    Element& faces = elements[face_element];
    header.face_count = faces.count;
    Property* indices = nullptr;
    for (Property& p : faces.properties) {
      if (p.name != "vertex_indices" && p.name != "vertex_index") continue;
      if (!p.list || !is_integer(p.type)) {
        return make_error(ErrorCode::kUnsupported,
                          fmt::format("{}: face property '{}' is not a list of integers", name, p.name));
      }
      indices = &p;
      break;
    }
    if (!indices) {
      return make_error(ErrorCode::kUnsupported,
                        fmt::format("{}: the face element has no 'vertex_indices' list", name));
    }
    indices->role = Role::kIndices;
    const bool index32 = indices->type == Type::kInt32 || indices->type == Type::kUint32;
    if (!ascii && !swap && faces.properties.size() == 1 && index32) {
      fast_face_count_bytes = static_cast<int>(type_bytes(indices->count_type));
      // A negative int32 index reads as a uint32 of at least 2^31: the bound rejects it too.
      const std::uint64_t limit = indices->type == Type::kInt32 ? std::uint64_t{1} << 31 : UINT32_MAX;
      fast_index_bound = static_cast<std::uint32_t>(std::min(header.vertex_count, limit));
    }
    return Ok{};
  }

  // A header's counts must fit in the file: a binary record takes at least its fixed bytes, an
  // ASCII value at least a character and a separator. Checked element by element, so a lying count
  // is an error at open and a truncated file names where it ends.
  Status check_size() {
    std::uint64_t offset = header.header_bytes;
    for (std::size_t i = 0; i < elements.size(); ++i) {
      const Element& e = elements[i];
      const std::uint64_t record_bytes = ascii ? 2 * e.properties.size() : e.fixed_bytes;
      if (record_bytes == 0) continue;
      // ASCII: the file's last value needs no separator after it.
      const std::uint64_t room = file_size - std::min(file_size, offset) + (ascii ? 1 : 0);
      if (e.count <= room / record_bytes) {
        offset += e.count * record_bytes;
        continue;
      }
      const std::uint64_t k = room / record_bytes;
      const std::string which = !ascii && !e.has_lists
                                    ? fmt::format("the file ends inside {}", record_label(i, k))
                                    : fmt::format("the file is too short for {} {} records", e.count, e.name);
      return make_error(ErrorCode::kCorrupt,
                        fmt::format("{}: truncated or impossible count: {} (element '{}' declares {} records "
                                    "of at least {} bytes from byte {}; the file has {} bytes)",
                                    name, which, e.name, e.count, record_bytes, offset, file_size));
    }
    if (header.vertex_count > UINT32_MAX) {
      return make_error(ErrorCode::kLimitExceeded, fmt::format("{}: {} vertices do not fit 32-bit vertex ids",
                                                               name, header.vertex_count));
    }
    return Ok{};
  }
};

Result<PlyReader> PlyReader::open(const std::filesystem::path& path) {
  auto state = std::make_unique<State>();
  state->name = path.string();
  const std::string& name = state->name;
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) {
    return make_error(ErrorCode::kNotFound, fmt::format("{}: no such file", name));
  }
  if (std::filesystem::is_directory(path, ec)) {
    return make_error(ErrorCode::kInvalidArgument, fmt::format("{}: is a directory, not a mesh file", name));
  }
  state->file_size = std::filesystem::file_size(path, ec);
  if (ec) return make_error(ErrorCode::kIoError, fmt::format("{}: cannot read size: {}", name, ec.message()));
  state->file = std::fopen(name.c_str(), "rb");
  if (!state->file) return make_error(ErrorCode::kIoError, fmt::format("{}: cannot open for reading", name));
  // Our buffer is the only one: stdio's would add a copy of every byte.
  std::setvbuf(state->file, nullptr, _IONBF, 0);
  state->buffer = std::make_unique_for_overwrite<unsigned char[]>(kReadBufferBytes);
  MTLOD_RETURN_IF_ERROR(state->parse_header());
  return PlyReader(std::move(state));
}

PlyReader::PlyReader(std::unique_ptr<State> state) : state_(std::move(state)) {}
PlyReader::PlyReader(PlyReader&&) noexcept = default;
PlyReader& PlyReader::operator=(PlyReader&&) noexcept = default;
PlyReader::~PlyReader() = default;

const PlyHeader& PlyReader::header() const {
  return state_->header;
}

Result<std::size_t> PlyReader::read_vertices(std::span<float> positions, std::span<float> normals,
                                             std::span<std::uint8_t> colors) {
  State& s = *state_;
  if (s.failure) return *s.failure;
  auto read = s.read_vertices(positions, normals, colors);
  if (!read.ok()) s.failure = read.error();
  return read;
}

Result<std::size_t> PlyReader::read_triangles(std::span<std::uint32_t> triangles) {
  State& s = *state_;
  if (s.failure) return *s.failure;
  auto read = s.read_triangles(triangles);
  if (!read.ok()) s.failure = read.error();
  return read;
}

std::uint64_t PlyReader::polygons_triangulated() const {
  return state_->polygons_triangulated;
}
std::uint64_t PlyReader::faces_dropped() const {
  return state_->faces_dropped;
}

// ---------------------------------------------------------------------------------------------------
// PlyWriter

struct PlyWriter::State {
  std::string name;
  std::FILE* file = nullptr;
  std::uint64_t vertex_count = 0;
  std::uint64_t triangle_count = 0;
  std::uint64_t vertices_written = 0;
  std::uint64_t triangles_written = 0;
  bool normals = false;
  bool colors = false;
  std::unique_ptr<unsigned char[]> buffer;
  std::size_t used = 0;
  bool failed = false;  // a write went wrong; reported by every later call
  bool closed = false;

  ~State() {
    if (!file) return;
    flush();
    std::fclose(file);
  }

  void flush() {
    if (used > 0 && !failed) failed = std::fwrite(buffer.get(), 1, used, file) != used;
    used = 0;
  }
  unsigned char* room(std::size_t bytes) {
    if (used + bytes > kWriteBufferBytes) flush();
    unsigned char* out = buffer.get() + used;
    used += bytes;
    return out;
  }
  Error write_failed() const {
    return make_error(ErrorCode::kIoError, fmt::format("{}: write failed", name));
  }
  Error invalid(std::string why) const {
    return make_error(ErrorCode::kInvalidArgument, fmt::format("{}: {}", name, why));
  }
};

Result<PlyWriter> PlyWriter::create(const std::filesystem::path& path, std::uint64_t vertex_count,
                                    std::uint64_t triangle_count, bool normals, bool colors) {
  auto state = std::make_unique<State>();
  state->name = path.string();
  if (vertex_count > UINT32_MAX) {
    return state->invalid(fmt::format("{} vertices do not fit 32-bit vertex ids", vertex_count));
  }
  state->file = std::fopen(state->name.c_str(), "wb");
  if (!state->file) {
    return make_error(ErrorCode::kIoError, fmt::format("{}: cannot open for writing", state->name));
  }
  state->vertex_count = vertex_count;
  state->triangle_count = triangle_count;
  state->normals = normals;
  state->colors = colors;
  state->buffer = std::make_unique_for_overwrite<unsigned char[]>(kWriteBufferBytes);
  std::string header = fmt::format(
      "ply\nformat binary_little_endian 1.0\ncomment written by mtlod\n"
      "element vertex {}\nproperty float x\nproperty float y\nproperty float z\n",
      vertex_count);
  if (normals) header += "property float nx\nproperty float ny\nproperty float nz\n";
  if (colors) header += "property uchar red\nproperty uchar green\nproperty uchar blue\n";
  header +=
      fmt::format("element face {}\nproperty list uchar uint vertex_indices\nend_header\n", triangle_count);
  std::memcpy(state->room(header.size()), header.data(), header.size());
  return PlyWriter(std::move(state));
}

PlyWriter::PlyWriter(std::unique_ptr<State> state) : state_(std::move(state)) {}
PlyWriter::PlyWriter(PlyWriter&&) noexcept = default;
PlyWriter& PlyWriter::operator=(PlyWriter&&) noexcept = default;
PlyWriter::~PlyWriter() = default;

Status PlyWriter::write_vertices(std::span<const float> positions, std::span<const float> normals,
                                 std::span<const std::uint8_t> colors) {
  State& s = *state_;
  if (s.closed) return s.invalid("write after close");
  if (s.failed) return s.write_failed();
  if (positions.size() % 3 != 0) {
    return s.invalid(fmt::format("{} position values are not whole vertices", positions.size()));
  }
  if (normals.size() != (s.normals ? positions.size() : 0) ||
      colors.size() != (s.colors ? positions.size() : 0)) {
    return s.invalid(fmt::format(
        "{} positions with {} normal and {} colour values; the file has {}normals and "
        "{}colours",
        positions.size(), normals.size(), colors.size(), s.normals ? "" : "no ", s.colors ? "" : "no "));
  }
  const std::size_t n = positions.size() / 3;
  if (n > s.vertex_count - s.vertices_written) {
    return s.invalid(fmt::format("{} more vertices after {} exceed the {} declared", n, s.vertices_written,
                                 s.vertex_count));
  }
  const std::size_t bytes = 12 + (s.normals ? 12 : 0) + (s.colors ? 3 : 0);
  for (std::size_t v = 0; v < n; ++v) {
    unsigned char* out = s.room(bytes);
    for (int c = 0; c < 3; ++c, out += 4) store_le(out, positions[3 * v + c]);
    for (int c = 0; c < 3 && s.normals; ++c, out += 4) store_le(out, normals[3 * v + c]);
    if (s.colors) std::memcpy(out, &colors[3 * v], 3);
  }
  s.vertices_written += n;
  if (s.failed) return s.write_failed();
  return Ok{};
}

Status PlyWriter::write_triangles(std::span<const std::uint32_t> triangles) {
  State& s = *state_;
  if (s.closed) return s.invalid("write after close");
  if (s.failed) return s.write_failed();
  if (triangles.size() % 3 != 0) {
    return s.invalid(fmt::format("{} vertex ids are not whole triangles", triangles.size()));
  }
  if (s.vertices_written < s.vertex_count) {
    return s.invalid(
        fmt::format("triangles written after {} of the {} vertices; PLY stores all vertices first",
                    s.vertices_written, s.vertex_count));
  }
  const std::size_t n = triangles.size() / 3;
  if (n > s.triangle_count - s.triangles_written) {
    return s.invalid(fmt::format("{} more triangles after {} exceed the {} declared", n, s.triangles_written,
                                 s.triangle_count));
  }
  for (std::size_t t = 0; t < n; ++t) {
    unsigned char* out = s.room(13);
    *out++ = 3;
    for (int c = 0; c < 3; ++c, out += 4) store_le(out, triangles[3 * t + c]);
  }
  s.triangles_written += n;
  if (s.failed) return s.write_failed();
  return Ok{};
}

Status PlyWriter::close() {
  State& s = *state_;
  if (s.closed) return s.invalid("closed twice");
  s.closed = true;
  s.flush();
  const bool closed_ok = std::fclose(s.file) == 0;
  s.file = nullptr;
  if (s.failed || !closed_ok) return s.write_failed();
  if (s.vertices_written != s.vertex_count || s.triangles_written != s.triangle_count) {
    return s.invalid(fmt::format("closed after {} of {} vertices and {} of {} triangles", s.vertices_written,
                                 s.vertex_count, s.triangles_written, s.triangle_count));
  }
  return Ok{};
}

}  // namespace mtlod::core::io
