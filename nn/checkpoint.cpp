#include "nn/checkpoint.h"

#include <charconv>

#include "autodiff/tape.h"

namespace sl::nn {

namespace {

constexpr const char* kOptimPrefix = "optim.";
// "optim." + name, built by append: GCC 12 warns falsely (-Wrestrict) on const char* + string.
std::string optim_key(const std::string& name) {
  std::string key(kOptimPrefix);
  key += name;
  return key;
}

constexpr const char* kReservedKeys[] = {"format", "streetlight_version", "stage", "step", "config"};

CheckpointInfo info_from(const std::string& path, const Metadata& meta) {
  CheckpointInfo info;
  for (const auto& [key, value] : meta) {
    if (key == "stage") info.stage = value;
    else if (key == "config") info.config_json = value;
    else if (key == "step") {
      const char* end = value.data() + value.size();
      const auto [p, ec] = std::from_chars(value.data(), end, info.step);
      SL_CHECK(ec == std::errc() && p == end && !value.empty(), path, ": metadata step '", value,
               "' is not an integer");
    } else if (key != "format" && key != "streetlight_version") {
      info.extra[key] = value;
    }
  }
  return info;
}

}  // namespace

void save_checkpoint(const std::string& path, const Module& model, const Optimizer* optimizer,
                     const CheckpointInfo& info) {
  StateDict all = model.state_dict();
  if (optimizer)
    for (const auto& [name, t] : optimizer->state_dict()) {
      const bool inserted = all.emplace(optim_key(name), t).second;
      SL_CHECK(inserted, "save_checkpoint ", path, ": model tensor name collides with optimiser state '",
               optim_key(name), "'");
    }
  Metadata meta = info.extra;
  for (const char* key : kReservedKeys)
    SL_CHECK(!meta.count(key), "save_checkpoint ", path, ": extra metadata key '", key, "' is reserved");
  meta.insert_or_assign("format", std::string("pt"));
  meta.insert_or_assign("streetlight_version", std::string(kCheckpointVersion));
  meta.insert_or_assign("stage", info.stage);
  meta.insert_or_assign("step", std::to_string(info.step));
  meta.insert_or_assign("config", info.config_json);
  write_safetensors(path, all, meta);
}

CheckpointInfo load_checkpoint(const std::string& path, Module& model, Optimizer* optimizer) {
  SafetensorsFile file = read_safetensors(path);
  StateDict expected = model.state_dict();
  if (optimizer)
    for (const auto& [name, t] : optimizer->state_dict()) expected.emplace(optim_key(name), t);
  StateDict given;
  for (const auto& [name, t] : file.tensors)
    if (optimizer || name.rfind(kOptimPrefix, 0) != 0) given.emplace(name, t);
  const StateMismatch m = compare_state(expected, given);
  SL_CHECK(m.empty(), path, ": checkpoint does not match the ", model.type_name(),
           optimizer ? cat(" and its ", optimizer->type_name(), " optimiser") : std::string(), ": ", m.message());
  NoGradGuard no_grad;
  for (auto& [name, t] : expected) t.copy_(given.at(name));
  return info_from(path, file.metadata);
}

CheckpointInfo read_checkpoint_info(const std::string& path) {
  return info_from(path, read_safetensors(path).metadata);
}

}  // namespace sl::nn
