#pragma once
#include <filesystem>
#include <functional>
#include <optional>
#include <ostream>
#include <string>
#include <vector>

namespace mgcloth {

/// Writes a file atomically: the content goes to a temporary file in the same folder (`<name>.tmp<pid>`), which is
/// then renamed over the target, so a reader (or an interrupted run) never sees a truncated file. When writing
/// fails (a full disk, or `write` throws) the temporary is removed and the target left as it was; the Error names
/// the target.
void write_file_atomic(const std::filesystem::path& path, const std::function<void(std::ostream&)>& write,
                       bool binary = false);
void write_file_atomic(const std::filesystem::path& path, const std::string& content);
std::string read_file(const std::filesystem::path& path);

/// The name of the file that `name` is write_file_atomic's temporary for (`<target>.tmp<digits>`); nullopt when
/// `name` is not such a temporary.
std::optional<std::string> atomic_write_target(const std::string& name);
/// Removes the temporaries of write_file_atomic in `dir` whose target names satisfy `ours`: those left behind by
/// a process that was killed while writing. Returns the paths removed.
std::vector<std::filesystem::path> remove_atomic_temporaries(const std::filesystem::path& dir,
                                                             const std::function<bool(const std::string&)>& ours);

}  // namespace mgcloth
