#include <mgcloth/core/log.hpp>
#include <spdlog/sinks/stdout_color_sinks.h>

namespace mgcloth {
namespace {
std::shared_ptr<spdlog::logger>& instance() {
  static std::shared_ptr<spdlog::logger> log = [] {
    auto l = spdlog::stderr_color_mt("mgcloth");
    l->set_pattern("[%l] %v");
    l->set_level(spdlog::level::warn);
    return l;
  }();
  return log;
}
}  // namespace

spdlog::logger& logger() { return *instance(); }
void set_logger(std::shared_ptr<spdlog::logger> l) { instance() = std::move(l); }

}  // namespace mgcloth
