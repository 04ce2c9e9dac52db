#pragma once
#include <spdlog/spdlog.h>

#include <memory>

namespace mgcloth {

/// The one logger of the library (stderr by default); the CLI and bindings may replace it.
spdlog::logger& logger();
void set_logger(std::shared_ptr<spdlog::logger> logger);

}  // namespace mgcloth
