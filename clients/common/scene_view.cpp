// A scene's view for the streaming tools (see scene_view.hpp).
#include "clients/common/scene_view.hpp"

#include "fmt/format.h"

namespace mtlod::clients {

Result<SceneView> describe_scene(ServerConnection& connection, const std::string& file,
                                 const std::vector<protocol::Instance>& instances,
                                 const ExtractFlags& flags) {
  const auto info = [&connection](const std::string& model) -> Result<protocol::ModelInfoReply> {
    MTLOD_TRY(const ReplyFrame reply, connection.call(protocol::ModelInfo{model}, 0));
    if (const auto* e = std::get_if<protocol::ErrorReply>(&reply.header.reply))
      return make_error(ErrorCode::kNotFound,
                        fmt::format("{}: {}", protocol::to_string(e->code), e->message));
    if (const auto* m = std::get_if<protocol::ModelInfoReply>(&reply.header.reply)) return *m;
    return make_error(ErrorCode::kCorrupt, fmt::format("model_info '{}': the reply is no model's", model));
  };
  const auto in_file = [&file](const Error& e) {
    return Error{e.code, fmt::format("{}: {}", file, e.message)};
  };
  SceneView view;
  auto box = scene_bounds(instances, info);
  if (!box) return in_file(box.error());
  view.box = *box;
  // A bad flag is the flag's error, whichever scene it was for.
  MTLOD_TRY(view.extract, make_scene_extract(flags, instances, view.box));
  return view;
}

}  // namespace mtlod::clients
