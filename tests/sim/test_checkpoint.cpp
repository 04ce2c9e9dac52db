// The checkpoint reader: what the writer wrote comes back exactly; anything else is an InputError naming the file
// and the problem, never a crash, a huge allocation or a state made of damaged bytes.
#include <mgcloth/core/error.hpp>
#include <mgcloth/sim/checkpoint.hpp>

#include <gtest/gtest.h>

#include <cstring>

using namespace mgcloth;

namespace {

const std::filesystem::path kFile = "/runs/a/checkpoint.bin";

sim::Checkpoint sample() {
  sim::Checkpoint c;
  c.fingerprint = 0x0123456789abcdefull;
  c.frame = 7;
  c.step = 14;
  c.bodies.push_back({VecX::LinSpaced(6, 0.0, 1.0), VecX::LinSpaced(6, -1.0, 0.5), ""});
  c.bodies.push_back({VecX::Constant(3, 2.5), VecX::Constant(3, -0.25), std::string("fmg\0state", 9)});
  return c;
}

/// The message of the InputError that decoding `bytes` throws; fails the test when it decodes.
std::string refusal(const std::string& bytes) {
  try {
    sim::decode_checkpoint(bytes, kFile);
  } catch (const InputError& e) {
    return e.what();
  }
  ADD_FAILURE() << "decoded " << bytes.size() << " bytes";
  return "";
}

/// `bytes` with its trailing checksum recomputed: damage that only a reader's own checks can catch.
std::string resealed(std::string bytes) {
  const std::uint64_t sum = sim::fnv1a(std::string_view(bytes).substr(0, bytes.size() - 8));
  std::memcpy(bytes.data() + bytes.size() - 8, &sum, 8);
  return bytes;
}

}  // namespace

TEST(Checkpoint, RoundTripsExactly) {
  const auto c = sample();
  const auto d = sim::decode_checkpoint(sim::encode_checkpoint(c), kFile);
  EXPECT_EQ(d.fingerprint, c.fingerprint);
  EXPECT_EQ(d.frame, 7);
  EXPECT_EQ(d.step, 14);
  ASSERT_EQ(d.bodies.size(), 2u);
  for (size_t k = 0; k < 2; ++k) {
    EXPECT_EQ(d.bodies[k].x, c.bodies[k].x);
    EXPECT_EQ(d.bodies[k].v, c.bodies[k].v);
    EXPECT_EQ(d.bodies[k].solver_state, c.bodies[k].solver_state);
  }
  EXPECT_EQ(sim::encode_checkpoint(sim::Checkpoint{}).substr(0, 8), "MGCKPT03");
}

TEST(Checkpoint, EveryFlippedByteIsRefused) {
  const std::string bytes = sim::encode_checkpoint(sample());
  for (size_t i = 0; i < bytes.size(); ++i) {
    std::string damaged = bytes;
    damaged[i] ^= 0x10;
    const std::string msg = refusal(damaged);
    EXPECT_EQ(msg.rfind(kFile.string() + ": ", 0), 0u) << "byte " << i << ": " << msg;
    if (i >= 8) {
      EXPECT_NE(msg.find("checksum mismatch"), std::string::npos) << "byte " << i << ": " << msg;
    }
  }
}

TEST(Checkpoint, EveryTruncationIsRefused) {
  const std::string bytes = sim::encode_checkpoint(sample());
  for (size_t n = 0; n < bytes.size(); ++n) {
    const std::string msg = refusal(bytes.substr(0, n));
    EXPECT_EQ(msg.rfind(kFile.string() + ": ", 0), 0u) << n << " bytes: " << msg;
    if (n >= 16) {
      EXPECT_NE(msg.find("checksum mismatch"), std::string::npos) << n << " bytes: " << msg;
    }
  }
  EXPECT_NE(refusal(bytes.substr(0, 12)).find("truncated"), std::string::npos);
}

TEST(Checkpoint, WrongMagicOrVersionIsNamed) {
  std::string bytes = sim::encode_checkpoint(sample());
  EXPECT_NE(refusal("hello, this is not a checkpoint").find("not an mgcloth checkpoint"), std::string::npos);
  std::string other = bytes;
  other[0] = 'X';
  EXPECT_NE(refusal(resealed(other)).find("not an mgcloth checkpoint"), std::string::npos);
  for (const char* version : {"01", "02"}) {
    other = bytes;
    other.replace(6, 2, version);
    const std::string msg = refusal(resealed(other));
    EXPECT_NE(msg.find(fmt::format("format version {}, written by an older mgcloth (this one reads 03)", version)),
              std::string::npos)
        << msg;
  }
  other = bytes;
  other.replace(6, 2, "04");
  EXPECT_NE(refusal(resealed(other)).find("format version 04, written by a newer mgcloth"), std::string::npos);
}

// Sizes that passed the checksum but do not describe the file (a crafted or mis-written one) are refused before
// anything is allocated for them.
TEST(Checkpoint, SizesBeyondTheFileAreRefused) {
  const std::string bytes = sim::encode_checkpoint(sample());
  constexpr size_t kBodyCount = 8 + 8 + 8 + 8, kFirstDofs = kBodyCount + 8;
  const auto with = [&](size_t offset, std::int64_t value) {
    std::string b = bytes;
    std::memcpy(b.data() + offset, &value, 8);
    return refusal(resealed(b));
  };
  EXPECT_NE(with(kBodyCount, std::int64_t(1) << 60).find("body count 1152921504606846976 does not fit"), std::string::npos);
  EXPECT_NE(with(kBodyCount, -1).find("body count -1 does not fit"), std::string::npos);
  EXPECT_NE(with(kFirstDofs, std::int64_t(1) << 61).find("dof count"), std::string::npos);
  const size_t first_state = kFirstDofs + 8 + 2 * 6 * sizeof(double);
  EXPECT_NE(with(first_state, 1000).find("solver state length 1000 does not fit"), std::string::npos);
  EXPECT_NE(with(kBodyCount, 1).find("bytes after the last body"), std::string::npos);
  EXPECT_NE(with(8 + 8, -3).find("frame -3"), std::string::npos);
}
