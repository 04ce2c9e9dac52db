#pragma once
#include <filesystem>
#include <functional>
#include <ostream>
#include <string>

namespace mgcloth {

/// Writes a file atomically: the content goes to a temporary file in the same folder, which is then renamed
/// over the target, so a reader (or an interrupted run) never sees a truncated file.
void write_file_atomic(const std::filesystem::path& path, const std::function<void(std::ostream&)>& write,
                       bool binary = false);
void write_file_atomic(const std::filesystem::path& path, const std::string& content);
std::string read_file(const std::filesystem::path& path);

}  // namespace mgcloth
