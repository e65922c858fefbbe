// A scene's view for the streaming tools (see scene_view.hpp).
#include "clients/common/scene_view.hpp"

#include "fmt/format.h"

namespace mtlod::clients {

Result<protocol::ModelInfoReply> model_info_reply(Result<ReplyFrame> reply) {
  if (!reply) return reply.take_error();
  if (const auto* e = std::get_if<protocol::ErrorReply>(&reply->header.reply))
    return make_error(ErrorCode::kNotFound, fmt::format("{}: {}", protocol::to_string(e->code), e->message));
  if (const auto* m = std::get_if<protocol::ModelInfoReply>(&reply->header.reply)) return *m;
  return make_error(ErrorCode::kCorrupt, "the reply to model_info describes no model");
}

Result<SceneView> describe_scene(ServerConnection& connection, const std::string& file,
                                 const std::vector<protocol::Instance>& instances,
                                 const ExtractFlags& flags) {
  const auto info = [&connection](const std::string& model) {
    return model_info_reply(connection.call(protocol::ModelInfo{model}, 0));
  };
  return describe_scene(info, file, instances, flags);
}

Result<SceneView> describe_scene(const ModelInfoFn& info, const std::string& file,
                                 const std::vector<protocol::Instance>& instances,
                                 const ExtractFlags& flags) {
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
