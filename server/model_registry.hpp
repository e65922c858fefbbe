// The models a server holds: Multi-Tessellations loaded from .mt files (a directory or a list),
// built from a mesh on first run when asked. Read-only once loaded, so workers share it without locks.
#pragma once

#include <cstddef>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "core/mt.hpp"
#include "core/occupancy_levels.hpp"
#include "core/result.hpp"
#include "protocol/replies.hpp"

namespace mtlod::server {

struct Model {
  std::string name;  // file stem: "bunny" for bunny.mt
  std::filesystem::path path;
  core::Mt mt;
  std::unique_ptr<core::OccupancyLevels> occupancy;  // coarse cuts for the occupancy stage
  std::size_t memory_bytes = 0;                      // held in memory: arrays read whole, coarse cuts
  std::size_t input_triangles = 0;
  float max_error = 0;  // largest triangle error
  float min_error = 0;  // smallest non-zero triangle error
  std::array<float, 3> bounds_min{}, bounds_max{};

  protocol::ModelSummary summary() const;
  protocol::ModelInfoReply info() const;
};

class ModelRegistry {
 public:
  // Loads one .mt file; its stem becomes the model name. Errors name the file.
  Status add_file(const std::filesystem::path& path);
  // Loads every .mt file of a directory (sorted by name).
  Status add_directory(const std::filesystem::path& dir);
  // Builds MODEL.mt from a mesh unless it exists, is newer than the mesh and has its vertices in
  // node order (older builds of mtlod-build numbered them otherwise), then loads it.
  Status add_mesh(const std::filesystem::path& mesh, const std::filesystem::path& mt_path);

  const Model* find(std::string_view name) const;
  const std::vector<std::unique_ptr<Model>>& models() const { return models_; }

 private:
  Status add(const std::filesystem::path& path, core::Mt mt);

  std::vector<std::unique_ptr<Model>> models_;
};

}  // namespace mtlod::server
