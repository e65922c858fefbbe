// The models a server holds: Multi-Tessellations loaded from .mt files (a directory or a list),
// built from a mesh on first run when asked, and loaded again when their files change.
//
// Each load makes a new immutable version (Model), shared by the registry, the sessions cutting
// from it and the workers' caches; the registry swaps versions under a lock, so a request sees one
// version from start to end. A version mapped from its file holds a read lease on it
// (core/io/file_lease.hpp): before another process may write the file, the version is retired —
// extractions in progress finish, later ones are refused with `unavailable` — and only then is
// the file handed over. Nothing in a version is read after it is retired, so no change to a file
// can fault the process or feed it half-written arrays.
#pragma once

#include <array>
#include <condition_variable>
#include <cstddef>
#include <filesystem>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "core/io/file_lease.hpp"
#include "core/model/mt.hpp"
#include "core/result.hpp"
#include "core/view/occupancy_levels.hpp"
#include "protocol/replies.hpp"

namespace mtlod::server {

// Extractions' right to read a version's arrays, against its retirement.
class ModelGate {
 public:
  // Held for one extraction; false (nothing held) once the version is retired.
  class Pass {
   public:
    Pass() = default;
    explicit Pass(const ModelGate* gate) : gate_(gate) {}
    Pass(Pass&& other) noexcept : gate_(std::exchange(other.gate_, nullptr)) {}
    Pass& operator=(Pass&&) = delete;
    ~Pass();
    explicit operator bool() const { return gate_ != nullptr; }

   private:
    const ModelGate* gate_ = nullptr;
  };
  Pass enter() const;
  // No pass is given from now on; returns once every pass given has ended.
  void retire() const;
  bool retired() const;

 private:
  mutable std::mutex mutex_;
  mutable std::condition_variable idle_;
  mutable std::size_t passes_ = 0;
  mutable bool retired_ = false;
};

struct Model {
  std::string name;  // file stem: "bunny" for bunny.mt
  std::filesystem::path path;
  core::model::Mt mt;
  std::unique_ptr<core::view::OccupancyLevels> occupancy;  // coarse cuts for the occupancy stage
  std::size_t memory_bytes = 0;                            // held in memory: arrays read whole, coarse cuts
  std::size_t input_triangles = 0;
  float max_error = 0;  // largest triangle error
  float min_error = 0;  // smallest non-zero triangle error
  std::array<float, 3> bounds_min{}, bounds_max{};

  std::uint64_t version = 1;                   // per name, from 1, one more at every load in this process
  std::uint64_t serial = 0;                    // unique in this process across names and versions
  core::io::FileIdentity file;                 // the file this version was read from
  std::unique_ptr<core::io::FileLease> lease;  // held while the arrays are mapped from the file
  std::string read_whole_because;              // why the file is in memory rather than mapped
  bool normals_computed = false;               // stored without normals: computed at load, in memory
  ModelGate gate;

  protocol::ModelSummary summary() const;
  protocol::ModelInfoReply info() const;
};
using ModelPtr = std::shared_ptr<const Model>;

class ModelRegistry {
 public:
  ModelRegistry();
  ~ModelRegistry();

  // Loads one .mt file; its stem becomes the model name. Errors name the file. The file is
  // watched from now on (reload()).
  Status add_file(const std::filesystem::path& path);
  // Loads every .mt file of a directory (sorted by name); later reloads also pick up files added to
  // it and drop those removed.
  Status add_directory(const std::filesystem::path& dir);
  // Builds MODEL.mt from a mesh unless it exists, is newer than the mesh and has its vertices in
  // node order (older builds of mtlod-build numbered them otherwise), then loads it.
  Status add_mesh(const std::filesystem::path& mesh, const std::filesystem::path& mt_path);

  // The version served now, or null.
  ModelPtr find(std::string_view name) const;
  // Every model served now, sorted by name.
  std::vector<ModelPtr> models() const;

  // Compares each model's file with the version served, loads what changed or appeared and drops
  // what is gone; a file that cannot be loaded leaves the served version (unless retired) in place
  // and says why. Safe from any thread; one reload runs at a time. `only`: just these names
  // (as a file-system watch reports them); empty: every model and every watched directory.
  std::vector<protocol::ModelReload> reload(const std::vector<std::string>& only = {});
  // A lease break arrived for descriptor fd (or, with -1, check every lease): retires the version
  // whose file a writer waits for and hands the file over. Returns the names retired.
  std::vector<std::string> hand_over_leases(int fd = -1);
  // Names to load again now without a file event: their files were held open by a writer, or were
  // handed over to one a while ago (reload() them).
  std::vector<std::string> due_pending() const;

  // The directories holding the files served and watched (for a file-system watch).
  std::vector<std::filesystem::path> watched_directories() const;
  // Which model a file name stands for ("dragon" for "dragon.mt"), if any.
  std::optional<std::string> model_for(const std::filesystem::path& dir, const std::string& file_name) const;

  std::uint64_t reloads() const;  // new versions loaded after start-up

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace mtlod::server
