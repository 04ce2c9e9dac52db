#pragma once
#include <mgcloth/core/json.hpp>
#include <mgcloth/bodies/shell_spec.hpp>

#include <filesystem>
#include <optional>

namespace mgcloth::sim {

using bodies::ShellBoundarySpec;
using bodies::ShellLoadSpec;
using bodies::ShellMeshSpec;
using bodies::ShellSelection;
using bodies::ShellSpec;

/// Parses one entry of a scene's "shells" (strict: unknown keys are InputError naming the JSON path).
ShellSpec parse_shell(JsonReader r, const std::filesystem::path& base, size_t index);
Json to_json(const ShellSpec& s);

}  // namespace mgcloth::sim
