// Scene files and boxes for the clients (see scene_file.hpp).
#include "clients/common/scene_file.hpp"

#include <algorithm>
#include <fstream>
#include <iterator>
#include <limits>
#include <map>

#include "fmt/format.h"
#include "protocol/parse.hpp"

namespace mtlod::clients {

Result<std::vector<protocol::Instance>> read_scene_file(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return make_error(ErrorCode::kIoError, fmt::format("{}: cannot open", path.string()));
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  // The server checks the instance limit; a file is not refused for it here.
  auto instances = protocol::parse_scene(text, protocol::Limits{.max_instances = UINT32_MAX});
  if (!instances) {
    return make_error(ErrorCode::kInvalidArgument,
                      fmt::format("{}: {}", path.string(), instances.error().message));
  }
  return std::move(*instances);
}

Result<SceneBox> scene_bounds(const std::vector<protocol::Instance>& instances, const ModelInfoFn& info) {
  constexpr double kInf = std::numeric_limits<double>::infinity();
  SceneBox box{{kInf, kInf, kInf}, {-kInf, -kInf, -kInf}};
  std::map<std::string, protocol::ModelInfoReply> models;
  for (const protocol::Instance& instance : instances) {
    auto found = models.find(instance.model);
    if (found == models.end()) {
      MTLOD_TRY(protocol::ModelInfoReply m, info(instance.model));
      found = models.emplace(instance.model, std::move(m)).first;
    }
    const protocol::ModelInfoReply& m = found->second;
    const protocol::Matrix4& a = instance.matrix;
    for (int k = 0; k < 8; ++k) {
      const double p[3] = {(k & 1) ? m.bounds_max[0] : m.bounds_min[0],
                           (k & 2) ? m.bounds_max[1] : m.bounds_min[1],
                           (k & 4) ? m.bounds_max[2] : m.bounds_min[2]};
      for (int r = 0; r < 3; ++r) {
        const double w = a[r] * p[0] + a[4 + r] * p[1] + a[8 + r] * p[2] + a[12 + r];
        box.min[r] = std::min(box.min[r], w);
        box.max[r] = std::max(box.max[r], w);
      }
    }
  }
  return box;
}

Result<protocol::Extract> make_scene_extract(const ExtractFlags& flags,
                                             std::vector<protocol::Instance> instances, const SceneBox& box) {
  MTLOD_TRY(protocol::Extract request, make_extract(flags, "", box.min, box.max));
  request.model.clear();
  request.instances = std::move(instances);
  return request;
}

}  // namespace mtlod::clients
