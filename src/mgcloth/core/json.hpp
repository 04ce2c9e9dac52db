#pragma once
#include <mgcloth/core/error.hpp>
#include <mgcloth/core/types.hpp>

#include <nlohmann/json.hpp>

#include <optional>
#include <set>
#include <string>
#include <vector>

namespace mgcloth {

using Json = nlohmann::json;

/// Strict, typed access to one JSON object of a user file. Every key read is marked as used; finish() rejects
/// the keys nobody read, by their full path, so a typo never passes silently. Errors name file and JSON path.
inline Json vec_json(const Vec3& v) { return Json::array({v.x(), v.y(), v.z()}); }
inline Json vec_json(const Vec2& v) { return Json::array({v.x(), v.y()}); }

class JsonReader {
 public:
  JsonReader(const Json& j, std::string file, std::string path = "");

  bool has(const std::string& key) const;
  const std::string& path() const { return m_path; }
  const std::string& file() const { return m_file; }
  std::string path_of(const std::string& key) const;

  /// Numbers: finite, within [lo, hi].
  double number(const std::string& key, double fallback, double lo = -kInf, double hi = kInf);
  double required_number(const std::string& key, double lo = -kInf, double hi = kInf);
  int integer(const std::string& key, int fallback, int lo = std::numeric_limits<int>::min(),
              int hi = std::numeric_limits<int>::max());
  bool boolean(const std::string& key, bool fallback);
  std::string string(const std::string& key, const std::string& fallback);
  std::string required_string(const std::string& key);
  /// A body's name (cloth, shell, obstacle). Names are written unquoted into CSV columns (stats.csv, trace.csv,
  /// probes.csv), folder names (`mgcloth hierarchy`) and log lines, so they are restricted rather than quoted
  /// everywhere: 1 to 64 bytes, no control character (newline, tab, NUL, ...), none of , " / \, and not "." or "..".
  /// Letters of any script, digits, spaces and other punctuation are fine.
  std::string name(const std::string& key, const std::string& fallback);
  /// A string from a closed set of choices.
  std::string choice(const std::string& key, const std::string& fallback, const std::vector<std::string>& choices);
  Vec3 vec3(const std::string& key, const Vec3& fallback);
  Vec2 vec2(const std::string& key, const Vec2& fallback);
  std::vector<double> numbers(const std::string& key);
  /// A list of [u, v] pairs (empty when the key is absent).
  std::vector<Vec2> vec2s(const std::string& key);
  std::vector<int> integers(const std::string& key, int lo = 0, int hi = std::numeric_limits<int>::max());

  JsonReader object(const std::string& key);
  std::optional<JsonReader> optional_object(const std::string& key);
  std::vector<JsonReader> objects(const std::string& key);
  const Json& raw(const std::string& key);

  /// Throws InputError naming the first key that was never read.
  void finish() const;
  [[noreturn]] void fail(const std::string& key, const std::string& what) const;

 private:
  const Json& at(const std::string& key);
  double to_number(const std::string& key, const Json& v, double lo, double hi) const;

  const Json* m_json;
  std::string m_file;
  std::string m_path;
  std::set<std::string> m_used;
};

/// Parses JSON text; syntax errors become InputError with file, line and column; so do a key given twice in one
/// object, a number beyond the range of a double and arrays or objects nested more than 256 deep (with the path).
Json parse_json(const std::string& text, const std::string& file);
Json load_json(const std::string& file);

}  // namespace mgcloth
