// What an extract request means to the core pipeline: protocol::Extract → core::ViewRequest and
// → the encoder's options. One translation shared by the server and the local mtlod-extract tool,
// so both compute the same cut and encode it into the same bytes.
#pragma once

#include <array>

#include "core/codec/draco_encode.hpp"
#include "core/view/view_extract.hpp"
#include "protocol/messages.hpp"

namespace mtlod::protocol {

// A wire matrix (column-major doubles) as GLM's floats.
glm::mat4 to_glm(const Matrix4& m);

// model_has_normals: back-face coarsening needs normals and is dropped without them.
core::view::ViewRequest to_view_request(const Extract& request, bool model_has_normals);

// What the encoder needs to know beyond the request.
struct EncodeContext {
  bool gaze = false;  // the request came as a gaze: the lowest-latency defaults
  bool model_has_colors = false;
  // The model's bounding box: delta payloads quantize positions on one grid made from it.
  std::array<float, 3> bounds_min{}, bounds_max{};
};

// The request's codec, what its payload carries (quantization, attributes, the model's grid and the
// cut's triangle order for deltas) and Draco's choices; unset ones get the defaults of DracoSettings:
// edgebreaker with entropy coding for an extract, sequential without for a gaze, sequential for
// deltas (the parser refuses explicit edgebreaker).
core::codec::EncodeOptions to_encode_options(const Extract& request, const EncodeContext& context);

}  // namespace mtlod::protocol
