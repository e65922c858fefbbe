// A scene's view for the streaming tools (mtlod-gaze, mtlod-load): the scene file's instances placed
// in a box from the models the server describes, and the flags' extract of the scene that frames it
// (PROTOCOL.md, "Scenes"). The set-up step before a stream's first request.
#pragma once

#include <string>
#include <vector>

#include "clients/common/extract_flags.hpp"
#include "clients/common/scene_file.hpp"
#include "clients/common/server_connection.hpp"
#include "core/result.hpp"
#include "protocol/messages.hpp"

namespace mtlod::clients {

struct SceneView {
  SceneBox box;               // every instance's model box, placed by its matrix
  protocol::Extract extract;  // make_scene_extract: the flags' camera, or one framing `box`
};

// A model_info call's reply as the model's description: an error reply becomes an error "code:
// message".
Result<protocol::ModelInfoReply> model_info_reply(Result<ReplyFrame> reply);

// Asks for each model of `instances` (`info`: model_info, once per model) and makes the scene's
// extract from `flags`. `file` names the scene in errors: "FILE: unknown_model: no model named 'x';
// loaded: ..." for a model the server refuses; a bad flag's error names the flag.
Result<SceneView> describe_scene(const ModelInfoFn& info, const std::string& file,
                                 const std::vector<protocol::Instance>& instances, const ExtractFlags& flags);
// The same over one connection.
Result<SceneView> describe_scene(ServerConnection& connection, const std::string& file,
                                 const std::vector<protocol::Instance>& instances, const ExtractFlags& flags);

}  // namespace mtlod::clients
