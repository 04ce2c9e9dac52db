#include <mgcloth/core/file_io.hpp>
#include <mgcloth/core/json.hpp>

#include <algorithm>
#include <cmath>

namespace mgcloth {

JsonReader::JsonReader(const Json& j, std::string file, std::string path)
    : m_json(&j), m_file(std::move(file)), m_path(std::move(path)) {
  if (!j.is_object()) {
    throw InputError(fmt::format("{}: {}: expected an object, got {}", m_file, m_path.empty() ? "(top level)" : m_path,
                                 j.type_name()));
  }
}

bool JsonReader::has(const std::string& key) const { return m_json->contains(key) && !(*m_json)[key].is_null(); }

std::string JsonReader::path_of(const std::string& key) const { return m_path.empty() ? key : m_path + "." + key; }

void JsonReader::fail(const std::string& key, const std::string& what) const {
  throw InputError(fmt::format("{}: {}: {}", m_file, path_of(key), what));
}

namespace {

/// Optimal string alignment distance: insertions, deletions, substitutions and swaps of neighbours cost one.
std::size_t edit_distance(const std::string& a, const std::string& b) {
  std::vector<std::vector<std::size_t>> d(a.size() + 1, std::vector<std::size_t>(b.size() + 1));
  for (std::size_t i = 0; i <= a.size(); ++i) d[i][0] = i;
  for (std::size_t j = 0; j <= b.size(); ++j) d[0][j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i)
    for (std::size_t j = 1; j <= b.size(); ++j) {
      d[i][j] = std::min({d[i - 1][j] + 1, d[i][j - 1] + 1, d[i - 1][j - 1] + (a[i - 1] != b[j - 1])});
      if (i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1]) d[i][j] = std::min(d[i][j], d[i - 2][j - 2] + 1);
    }
  return d[a.size()][b.size()];
}

/// Whether `typed` is probably a misspelling of `meant`: up to one edit, two from six letters on.
bool looks_like(const std::string& typed, const std::string& meant) {
  if (typed == meant) return false;
  const std::size_t allowed = std::max(typed.size(), meant.size()) >= 6 ? 2 : 1;
  return (typed.size() > meant.size() ? typed.size() - meant.size() : meant.size() - typed.size()) <= allowed &&
         edit_distance(typed, meant) <= allowed;
}

}  // namespace

const Json& JsonReader::at(const std::string& key) {
  m_used.insert(key);
  if (!m_json->contains(key)) {
    // A misspelled key is the likelier mistake than a missing one: report it, as finish() would have.
    for (auto it = m_json->begin(); it != m_json->end(); ++it)
      if (!m_used.count(it.key()) && looks_like(it.key(), key))
        fail(it.key(), fmt::format("unknown key (did you mean \"{}\"?)", key));
    fail(key, "missing required field");
  }
  return (*m_json)[key];
}

const Json& JsonReader::raw(const std::string& key) { return at(key); }

double JsonReader::to_number(const std::string& key, const Json& v, double lo, double hi) const {
  if (!v.is_number()) fail(key, fmt::format("expected a number, got {} {}", v.type_name(), v.dump()));
  const double d = v.get<double>();
  if (!std::isfinite(d)) fail(key, "expected a finite number");
  if (d < lo || d > hi) {
    if (hi == kInf) fail(key, fmt::format("must be >= {}, got {}", lo, d));
    if (lo == -kInf) fail(key, fmt::format("must be <= {}, got {}", hi, d));
    fail(key, fmt::format("must be in [{}, {}], got {}", lo, hi, d));
  }
  return d;
}

double JsonReader::number(const std::string& key, double fallback, double lo, double hi) {
  m_used.insert(key);
  if (!has(key)) return fallback;
  return to_number(key, (*m_json)[key], lo, hi);
}

double JsonReader::required_number(const std::string& key, double lo, double hi) {
  return to_number(key, at(key), lo, hi);
}

int JsonReader::integer(const std::string& key, int fallback, int lo, int hi) {
  m_used.insert(key);
  if (!has(key)) return fallback;
  const Json& v = (*m_json)[key];
  if (!v.is_number_integer()) fail(key, fmt::format("expected an integer, got {}", v.dump()));
  const auto i = v.get<long long>();
  if (i < lo || i > hi) fail(key, fmt::format("must be in [{}, {}], got {}", lo, hi, i));
  return static_cast<int>(i);
}

bool JsonReader::boolean(const std::string& key, bool fallback) {
  m_used.insert(key);
  if (!has(key)) return fallback;
  const Json& v = (*m_json)[key];
  if (!v.is_boolean()) fail(key, fmt::format("expected true or false, got {}", v.dump()));
  return v.get<bool>();
}

std::string JsonReader::string(const std::string& key, const std::string& fallback) {
  m_used.insert(key);
  if (!has(key)) return fallback;
  const Json& v = (*m_json)[key];
  if (!v.is_string()) fail(key, fmt::format("expected a string, got {}", v.dump()));
  return v.get<std::string>();
}

std::string JsonReader::name(const std::string& key, const std::string& fallback) {
  const std::string n = string(key, fallback);
  const auto bad = [&](const std::string& why) {
    fail(key, fmt::format("{} {}: a name goes unquoted into CSV columns and folder names (1 to 64 bytes; no control "
                          "characters, no , \" / \\)",
                          Json(n).dump(), why));
  };
  if (n.empty()) bad("is empty");
  if (n.size() > 64) bad(fmt::format("is {} bytes long", n.size()));
  if (n == "." || n == "..") bad("is a folder name");
  for (const char c : n) {
    const auto u = static_cast<unsigned char>(c);
    if (u < 0x20 || u == 0x7f) bad(fmt::format("contains the control character 0x{:02x}", u));
    if (c == ',' || c == '"' || c == '/' || c == '\\') bad(fmt::format("contains '{}'", c));
  }
  return n;
}

std::string JsonReader::required_string(const std::string& key) {
  const Json& v = at(key);
  if (!v.is_string()) fail(key, fmt::format("expected a string, got {}", v.dump()));
  return v.get<std::string>();
}

std::string JsonReader::choice(const std::string& key, const std::string& fallback,
                               const std::vector<std::string>& choices) {
  std::string s = string(key, fallback);
  for (const auto& c : choices)
    if (c == s) return s;
  fail(key, fmt::format("unknown value \"{}\" (expected one of: {})", s, fmt::join(choices, ", ")));
}

std::vector<double> JsonReader::numbers(const std::string& key) {
  const Json& v = at(key);
  if (!v.is_array()) fail(key, fmt::format("expected an array of numbers, got {}", v.dump()));
  std::vector<double> out;
  for (size_t i = 0; i < v.size(); ++i) out.push_back(to_number(fmt::format("{}[{}]", key, i), v[i], -kInf, kInf));
  return out;
}

std::vector<int> JsonReader::integers(const std::string& key, int lo, int hi) {
  const Json& v = at(key);
  if (!v.is_array()) fail(key, fmt::format("expected an array of integers, got {}", v.dump()));
  std::vector<int> out;
  for (size_t i = 0; i < v.size(); ++i) {
    if (!v[i].is_number_integer()) fail(fmt::format("{}[{}]", key, i), fmt::format("expected an integer, got {}", v[i].dump()));
    const auto k = v[i].get<long long>();
    if (k < lo || k > hi) fail(fmt::format("{}[{}]", key, i), fmt::format("must be in [{}, {}], got {}", lo, hi, k));
    out.push_back(static_cast<int>(k));
  }
  return out;
}

Vec3 JsonReader::vec3(const std::string& key, const Vec3& fallback) {
  m_used.insert(key);
  if (!has(key)) return fallback;
  const auto v = numbers(key);
  if (v.size() != 3) fail(key, fmt::format("expected 3 numbers, got {}", v.size()));
  return {v[0], v[1], v[2]};
}

Vec2 JsonReader::vec2(const std::string& key, const Vec2& fallback) {
  m_used.insert(key);
  if (!has(key)) return fallback;
  const auto v = numbers(key);
  if (v.size() != 2) fail(key, fmt::format("expected 2 numbers, got {}", v.size()));
  return {v[0], v[1]};
}

std::vector<Vec2> JsonReader::vec2s(const std::string& key) {
  m_used.insert(key);
  std::vector<Vec2> out;
  if (!has(key)) return out;
  const Json& pts = at(key);
  if (!pts.is_array()) fail(key, "expected an array of [u, v] pairs");
  for (size_t i = 0; i < pts.size(); ++i) {
    if (!pts[i].is_array() || pts[i].size() != 2 || !pts[i][0].is_number() || !pts[i][1].is_number())
      fail(fmt::format("{}[{}]", key, i), "expected [u, v] (two numbers)");
    const Vec2 p(pts[i][0].get<double>(), pts[i][1].get<double>());
    if (!p.allFinite()) fail(fmt::format("{}[{}]", key, i), "must be finite");
    out.push_back(p);
  }
  return out;
}

JsonReader JsonReader::object(const std::string& key) { return JsonReader(at(key), m_file, path_of(key)); }

std::optional<JsonReader> JsonReader::optional_object(const std::string& key) {
  m_used.insert(key);
  if (!has(key)) return std::nullopt;
  return JsonReader((*m_json)[key], m_file, path_of(key));
}

std::vector<JsonReader> JsonReader::objects(const std::string& key) {
  m_used.insert(key);
  std::vector<JsonReader> out;
  if (!has(key)) return out;
  const Json& v = (*m_json)[key];
  if (!v.is_array()) fail(key, fmt::format("expected an array of objects, got {}", v.type_name()));
  for (size_t i = 0; i < v.size(); ++i) out.emplace_back(v[i], m_file, fmt::format("{}[{}]", path_of(key), i));
  return out;
}

void JsonReader::finish() const {
  for (auto it = m_json->begin(); it != m_json->end(); ++it) {
    // null means "absent" everywhere, so an explicit null is never an unknown key.
    if (m_used.count(it.key()) || it.value().is_null()) continue;
    for (const std::string& known : m_used)
      if (looks_like(it.key(), known)) fail(it.key(), fmt::format("unknown key (did you mean \"{}\"?)", known));
    fail(it.key(), "unknown key");
  }
}

namespace {

/// Follows nlohmann's parser through the document (its callback sees every key and value), so that what the parser
/// itself accepts silently (a key given twice: the last one would win) or reports without a place (a number that
/// overflows a double) is reported with its JSON path.
class PathTracker {
 public:
  static constexpr std::size_t kMaxJsonDepth = 256;

  explicit PathTracker(const std::string& file) : m_file(file) {}

  bool operator()(int /*depth*/, Json::parse_event_t event, Json& parsed) {
    using E = Json::parse_event_t;
    switch (event) {
      case E::object_start:
      case E::array_start:
        // nlohmann parses any depth, but copying, printing and comparing values recurse: a file of 200,000 nested
        // brackets overflowed the stack (a segmentation fault) instead of being an error.
        if (m_frames.size() >= kMaxJsonDepth)
          throw InputError(fmt::format("{}: {}: arrays and objects nested more than {} deep", m_file, path(),
                                       kMaxJsonDepth));
        m_frames.push_back({event == E::object_start});
        break;
      case E::key: {
        Frame& f = m_frames.back();
        f.key = parsed.get<std::string>();
        if (!f.keys.insert(f.key).second)
          throw InputError(fmt::format("{}: {}: duplicate key \"{}\": an object gives it twice (remove one; mgcloth "
                                       "does not pick either)",
                                       m_file, path(), f.key));
        break;
      }
      case E::object_end:
      case E::array_end:
        m_frames.pop_back();
        next_element();
        break;
      case E::value: next_element(); break;
    }
    return true;
  }

  /// The path of the element being parsed: "cloths[0].mesh.vertices"; "(top level)" outside every object.
  std::string path() const {
    std::string p;
    for (const Frame& f : m_frames) {
      if (!f.object) p += fmt::format("[{}]", f.index);
      else if (!f.keys.empty()) p += (p.empty() ? "" : ".") + f.key;
    }
    return p.empty() ? "(top level)" : p;
  }

 private:
  struct Frame {
    bool object;
    std::set<std::string> keys = {};
    std::string key = {};
    std::size_t index = 0;
  };
  void next_element() {
    if (!m_frames.empty() && !m_frames.back().object) ++m_frames.back().index;
  }

  const std::string& m_file;
  std::vector<Frame> m_frames;
};

}  // namespace

Json parse_json(const std::string& text, const std::string& file) {
  PathTracker tracker(file);
  try {
    return Json::parse(text, [&tracker](int depth, Json::parse_event_t event, Json& parsed) {
      return tracker(depth, event, parsed);
    });
  } catch (const Json::out_of_range& e) {
    // "[json.exception.out_of_range.406] number overflow parsing '1e400'": a number beyond the range of a double.
    const std::string what = e.what();
    const auto pos = what.find("] ");
    throw InputError(fmt::format("{}: {}: {} (beyond the range of a double)", file, tracker.path(),
                                 pos == std::string::npos ? what : what.substr(pos + 2)));
  } catch (const Json::parse_error& e) {
    // nlohmann reports a byte offset; turn it into line:column for the user.
    size_t line = 1, col = 1;
    for (size_t i = 0; i < std::min(e.byte, text.size() + 1) - 1 && i < text.size(); ++i) {
      if (text[i] == '\n') {
        ++line;
        col = 1;
      } else {
        ++col;
      }
    }
    std::string what = e.what();
    const auto pos = what.find("syntax error");
    throw InputError(fmt::format("{}:{}:{}: malformed JSON: {}", file, line, col,
                                 pos == std::string::npos ? what : what.substr(pos)));
  }
}

Json load_json(const std::string& file) { return parse_json(read_file(file), file); }

}  // namespace mgcloth
