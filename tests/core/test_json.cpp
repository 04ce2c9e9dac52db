#include <mgcloth/core/error.hpp>
#include <mgcloth/core/json.hpp>

#include <gtest/gtest.h>

namespace mgcloth {
namespace {

std::string parse_error(const std::string& text) {
  try {
    parse_json(text, "scene.json");
  } catch (const InputError& e) {
    return e.what();
  } catch (const std::exception& e) {
    return std::string("not an InputError: ") + e.what();
  }
  return "";
}

// nlohmann's parser keeps the last of two equal keys without a word; a scene that says "frames" twice is a mistake.
TEST(Json, DuplicateKeysAreErrorsNamingKeyAndPath) {
  EXPECT_EQ(parse_error(R"({"frames": 3, "frames": 4})"),
            "scene.json: frames: duplicate key \"frames\": an object gives it twice (remove one; mgcloth does not "
            "pick either)");
  const std::string nested = parse_error(R"({"cloths": [ {"name": "a"},
    {"mesh": {"vertices": 10, "width": 1, "vertices": 20}} ]})");
  EXPECT_NE(nested.find("scene.json: cloths[1].mesh.vertices: duplicate key \"vertices\""), std::string::npos) << nested;
  const std::string in_array = parse_error(R"({"obstacles": [ 1, [2, {"a": 1, "a": 2}] ]})");
  EXPECT_NE(in_array.find("scene.json: obstacles[1][1].a: duplicate key \"a\""), std::string::npos) << in_array;
  // The same key in different objects is fine, and so is the document as a whole.
  const Json ok = parse_json(R"({"a": {"x": 1}, "b": {"x": 2}, "c": [{"x": 3}, {"x": 4}]})", "ok.json");
  EXPECT_EQ(ok["c"][1]["x"], 4);
}

// The parser throws its own out_of_range ("[json.exception.out_of_range.406] number overflow parsing '1e400'") with
// neither file nor field.
TEST(Json, NumbersBeyondADoubleNameFileAndPath) {
  EXPECT_EQ(parse_error(R"({"time_step": 1e400})"),
            "scene.json: time_step: number overflow parsing '1e400' (beyond the range of a double)");
  const std::string in_array = parse_error(R"({"gravity": [0, 0, -1e999]})");
  EXPECT_NE(in_array.find("scene.json: gravity[2]: number overflow parsing '-1e999'"), std::string::npos) << in_array;
  EXPECT_NE(parse_error("1e400").find("scene.json: (top level): number overflow"), std::string::npos);
}

// Deep nesting is parsed without recursion but copied, printed and compared recursively: 200,000 brackets crashed
// `mgcloth run` with a segmentation fault.
TEST(Json, NestingDeeperThan256IsAnError) {
  const auto nested = [](int depth) {
    return R"({"cloths": [{"mesh": {}}], "solver": {"params": )" + std::string(depth, '[') + std::string(depth, ']') +
           "}}";
  };
  // Two objects (the top level, solver) hold the params arrays: 254 of them make 256 levels.
  EXPECT_NO_THROW(parse_json(nested(254), "scene.json"));
  std::string path = "solver.params";
  for (int i = 0; i < 254; ++i) path += "[0]";  // the innermost array is the 255th
  EXPECT_EQ(parse_error(nested(255)), "scene.json: " + path + ": arrays and objects nested more than 256 deep");
  const std::string deep = parse_error(nested(200000));
  EXPECT_NE(deep.find(": arrays and objects nested more than 256 deep"), std::string::npos) << deep.substr(0, 200);
}

}  // namespace
}  // namespace mgcloth
