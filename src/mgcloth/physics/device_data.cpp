#include <mgcloth/core/error.hpp>
#include <mgcloth/physics/device_data.hpp>

namespace mgcloth::physics {

void DeviceObjective::claim(bool& kind, const std::string& term) {
  if (kind) throw InputError(fmt::format("fmg-cuda: the objective has two \"{}\" terms; the device pipeline takes one", term));
  kind = true;
}

}  // namespace mgcloth::physics
