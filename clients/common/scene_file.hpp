// Scenes for the clients (PROTOCOL.md, "Scenes"): a scene file read and checked as a request's
// scene is, its bounding box in the world from the served models' bounds, and the extract that
// frames it with the same flags as a single model's.
#pragma once

#include <array>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "clients/common/extract_flags.hpp"
#include "core/result.hpp"
#include "protocol/replies.hpp"

namespace mtlod::clients {

// The instances of a scene file ({"instances": [{"model", "matrix"}, ...]}); errors name the file
// and the field.
Result<std::vector<protocol::Instance>> read_scene_file(const std::filesystem::path& path);

struct SceneBox {
  std::array<double, 3> min{}, max{};
};
// A model's description, as the server gives it (model_info), or why not.
using ModelInfoFn = std::function<Result<protocol::ModelInfoReply>(const std::string& model)>;
// The box holding every instance's model box, its corners placed by the instance's matrix; `info`
// is asked once per model.
Result<SceneBox> scene_bounds(const std::vector<protocol::Instance>& instances, const ModelInfoFn& info);

// The flags' extract (make_extract: the camera frames `box` unless --eye is given) for the scene.
Result<protocol::Extract> make_scene_extract(const ExtractFlags& flags,
                                             std::vector<protocol::Instance> instances, const SceneBox& box);

}  // namespace mtlod::clients
