#include <mgcloth/core/error.hpp>
#include <mgcloth/sim/checkpoint.hpp>

#include <cstring>
#include <limits>

namespace mgcloth::sim {

namespace fs = std::filesystem;

namespace {
constexpr std::string_view kMagicPrefix = "MGCKPT";
constexpr std::size_t kMagicBytes = 8, kChecksumBytes = sizeof(std::uint64_t);

template <class T>
void put(std::string& out, const T& value) {
  out.append(reinterpret_cast<const char*>(&value), sizeof(T));
}

/// Reads the payload front to back; every read is checked against what is left, so that sizes in a file that
/// passed the checksum but was not written by encode_checkpoint cannot read or allocate past its end.
class Reader {
 public:
  Reader(std::string_view bytes, const fs::path& file) : m_bytes(bytes), m_file(file) {}
  template <class T>
  T get(const char* what) {
    need(sizeof(T), what);
    T value;
    std::memcpy(&value, m_bytes.data() + m_pos, sizeof(T));
    m_pos += sizeof(T);
    return value;
  }
  /// A count of `unit`-byte items that must fit in what is left.
  std::size_t count(std::size_t unit, const char* what) {
    const auto n = get<std::int64_t>(what);
    if (n < 0 || static_cast<std::uint64_t>(n) > left() / unit)
      throw_input_error("{}: {} {} does not fit in the checkpoint's remaining {} bytes", m_file.string(), what, n, left());
    return static_cast<std::size_t>(n);
  }
  VecX doubles(std::size_t n, const char* what) {
    need(n * sizeof(double), what);
    VecX v(static_cast<Index>(n));
    if (n > 0) std::memcpy(v.data(), m_bytes.data() + m_pos, n * sizeof(double));
    m_pos += n * sizeof(double);
    return v;
  }
  std::string chars(std::size_t n, const char* what) {
    need(n, what);
    std::string s(m_bytes.substr(m_pos, n));
    m_pos += n;
    return s;
  }
  std::size_t left() const { return m_bytes.size() - m_pos; }

 private:
  void need(std::size_t n, const char* what) const {
    if (n > left()) throw_input_error("{}: ends inside {}", m_file.string(), what);
  }
  std::string_view m_bytes;
  std::size_t m_pos = 0;
  const fs::path& m_file;
};

/// The version number of a magic "MGCKPTnn"; −1 when it is not one.
int magic_version(std::string_view bytes) {
  if (bytes.size() < kMagicBytes || bytes.substr(0, kMagicPrefix.size()) != kMagicPrefix) return -1;
  const char a = bytes[6], b = bytes[7];
  if (a < '0' || a > '9' || b < '0' || b > '9') return -1;
  return 10 * (a - '0') + (b - '0');
}
}  // namespace

std::uint64_t fnv1a(std::string_view bytes) {
  std::uint64_t h = 1469598103934665603ull;
  for (unsigned char c : bytes) {
    h ^= c;
    h *= 1099511628211ull;
  }
  return h;
}

std::string encode_checkpoint(const Checkpoint& c) {
  std::string out = fmt::format("{}{:02d}", kMagicPrefix, kCheckpointVersion);
  put(out, c.fingerprint);
  put<std::int64_t>(out, c.frame);
  put<std::int64_t>(out, c.step);
  put<std::int64_t>(out, static_cast<std::int64_t>(c.bodies.size()));
  for (const auto& b : c.bodies) {
    if (b.v.size() != b.x.size())
      throw_error("checkpoint: a body has {} position and {} velocity values", b.x.size(), b.v.size());
    put<std::int64_t>(out, b.x.size());
    out.append(reinterpret_cast<const char*>(b.x.data()), sizeof(double) * static_cast<std::size_t>(b.x.size()));
    out.append(reinterpret_cast<const char*>(b.v.data()), sizeof(double) * static_cast<std::size_t>(b.v.size()));
    put<std::int64_t>(out, static_cast<std::int64_t>(b.solver_state.size()));
    out += b.solver_state;
  }
  put(out, fnv1a(out));
  return out;
}

Checkpoint decode_checkpoint(std::string_view bytes, const fs::path& file) {
  const int version = magic_version(bytes);
  if (version < 0) throw_input_error("{}: not an mgcloth checkpoint", file.string());
  if (version < kCheckpointVersion)
    throw_input_error("{}: checkpoint format version {:02d}, written by an older mgcloth (this one reads {:02d}); "
                      "start a new run instead of --resume",
                      file.string(), version, kCheckpointVersion);
  if (version > kCheckpointVersion)
    throw_input_error("{}: checkpoint format version {:02d}, written by a newer mgcloth (this one reads {:02d})",
                      file.string(), version, kCheckpointVersion);
  if (bytes.size() < kMagicBytes + kChecksumBytes)
    throw_input_error("{}: truncated checkpoint ({} bytes)", file.string(), bytes.size());
  const std::string_view payload = bytes.substr(0, bytes.size() - kChecksumBytes);
  std::uint64_t sum = 0;
  std::memcpy(&sum, bytes.data() + payload.size(), sizeof(sum));
  if (sum != fnv1a(payload))
    throw_input_error("{}: checksum mismatch: the checkpoint is corrupted or truncated (nothing was changed; start a "
                      "new run or restore the file)",
                      file.string());

  Reader in(payload.substr(kMagicBytes), file);
  Checkpoint c;
  c.fingerprint = in.get<std::uint64_t>("the scene fingerprint");
  c.frame = in.get<std::int64_t>("the frame number");
  c.step = in.get<std::int64_t>("the step number");
  if (c.frame < 0 || c.frame > std::numeric_limits<int>::max() || c.step < 0)
    throw_input_error("{}: frame {} at step {} is not a state of a run", file.string(), c.frame, c.step);
  // Each body takes at least its two length fields.
  c.bodies.resize(in.count(2 * sizeof(std::int64_t), "body count"));
  for (auto& b : c.bodies) {
    const std::size_t n = in.count(2 * sizeof(double), "dof count");
    b.x = in.doubles(n, "positions");
    b.v = in.doubles(n, "velocities");
    b.solver_state = in.chars(in.count(1, "solver state length"), "a solver state");
  }
  if (in.left() != 0) throw_input_error("{}: {} bytes after the last body", file.string(), in.left());
  return c;
}

}  // namespace mgcloth::sim
