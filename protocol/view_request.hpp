// What an extract request means to the core pipeline: protocol::Extract → core::ViewRequest. One
// translation shared by the server and the local mtlod-extract tool, so both compute the same cut.
#pragma once

#include "core/view/view_extract.hpp"
#include "protocol/messages.hpp"

namespace mtlod::protocol {

// model_has_normals: back-face coarsening needs normals and is dropped without them.
core::view::ViewRequest to_view_request(const Extract& request, bool model_has_normals);

}  // namespace mtlod::protocol
