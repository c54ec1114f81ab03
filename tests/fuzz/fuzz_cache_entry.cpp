// libFuzzer harness: the cache entries' decoders (decode_model_entry, decode_features_entry,
// decode_samples_entry). A checksum guards every payload, so mutated bytes alone would never get
// past it: the input's first byte picks what it is, the rest is
//   0: a converted-model payload, wrapped in a well-formed header with its size and checksum;
//   1: a model-features payload, wrapped likewise (features of a small saddle model);
//   2, 3: a whole model / features entry as it stands (the header checks themselves);
//   4: a payload of the features' samples alone (area, voxel, keypoints), wrapped likewise;
//   5: a whole entry of the samples as it stands.
// A decode either gives what an entry can hold (a valid model; features whose parts fit the
// model) or throws CacheEntryError with one printable line; anything else aborts.
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <string>
#include <string_view>

#include "nurbsreg/engine/prepared_model.hpp"
#include "nurbsreg/io/features_cache.hpp"
#include "nurbsreg/io/model_cache.hpp"
#include "nurbsreg/registration/model_features.hpp"
#include "support/saddle_model.hpp"

namespace {

using namespace nurbsreg;

const std::string kVersion = "fuzz";

struct Fixture {
  engine::Model model = test::saddle_model();
  engine::PreparedModel prepared{test::saddle_model()};
  io::ContentHash model_hash = io::hash_model(model);
  registration::FeatureOptions options;
  std::string model_entry, features_entry, samples_entry;

  Fixture() {
    options.keypoints = 20;  // small entries: the fuzzer's inputs stay short
    model_entry = io::encode_model_entry(model, model_hash, 1234, kVersion);
    const registration::ModelFeatures features(prepared, options);
    features_entry = io::encode_features_entry(features, model_hash, kVersion);
    samples_entry = io::encode_samples_entry(features, model_hash, kVersion);
  }
};

const Fixture& fixture() {
  static const Fixture f;
  return f;
}

// The header of `entry` ends with the payload's size and checksum: found as the offset h where
// the size field (at h - 16) equals entry.size() - h. Returns an entry with `payload` instead.
std::string with_payload(const std::string& entry, std::string_view payload) {
  for (std::size_t h = 16; h <= entry.size(); ++h) {
    std::uint64_t size = 0;
    std::memcpy(&size, entry.data() + h - 16, 8);
    if (size != entry.size() - h) continue;
    std::string out = entry.substr(0, h);
    out.append(payload);
    const std::uint64_t new_size = payload.size(), check = io::hash_bytes(payload).lo;
    std::memcpy(out.data() + h - 16, &new_size, 8);
    std::memcpy(out.data() + h - 8, &check, 8);
    return out;
  }
  std::abort();  // the encoders' layout changed: the harness must follow
}

void check_message(const io::CacheEntryError& e) {
  const std::string m = e.what();
  bool printable = !m.empty();
  for (const char ch : m)
    printable = printable && static_cast<unsigned char>(ch) >= 0x20 &&
                static_cast<unsigned char>(ch) <= 0x7e;
  if (!printable) {
    std::fprintf(stderr, "not one printable line: %s\n", m.c_str());
    std::abort();
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  const Fixture& f = fixture();
  const std::string_view rest(reinterpret_cast<const char*>(data) + 1, size - 1);
  const int kind = data[0] % 6;
  try {
    if (kind == 0 || kind == 2) {
      const std::string bytes = kind == 0 ? with_payload(f.model_entry, rest) : std::string(rest);
      const engine::Model m = io::decode_model_entry(bytes, f.model_hash, 1234, kVersion);
      if (m.validate()) std::abort();  // a decoded model is a valid one
    } else {
      std::shared_ptr<const registration::ModelFeatures> features;
      if (kind == 1 || kind == 3) {
        const std::string bytes =
            kind == 1 ? with_payload(f.features_entry, rest) : std::string(rest);
        features = io::decode_features_entry(bytes, f.prepared, f.model_hash, f.options, kVersion);
      } else {
        const std::string bytes =
            kind == 4 ? with_payload(f.samples_entry, rest) : std::string(rest);
        features = io::decode_samples_entry(bytes, f.prepared, f.model_hash, f.options, kVersion);
      }
      const auto& k = features->keypoints();
      // Samples build the descriptors from their keypoints here: a build over what was read.
      if (k.normals.size() != k.points.size() ||
          static_cast<std::size_t>(features->descriptors().rows()) !=
              features->described_keypoints().points.size()) {
        std::abort();
      }
      const engine::Aabb& box = f.prepared.bounds();
      const double margin = 1e-6 * box.diagonal();
      for (const engine::Vec3& p : k.points) {
        if (!p.allFinite()) std::abort();
        // Decoded keypoints are samples of the model's faces.
        if (box.squared_distance(p) > margin * margin) std::abort();
      }
    }
  } catch (const io::CacheEntryError& e) {
    check_message(e);
  }
  return 0;
}
