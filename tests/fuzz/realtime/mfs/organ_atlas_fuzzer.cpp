// libFuzzer harness of the organ atlas reader (the JSON `touchstone atlas` writes and the
// enriched model reads for its body-aware exterior): the bytes as an atlas file, read, then
// looked up at each sample's own contact (its tool radius, local radius and ν) and halfway
// between the first two samples. std::runtime_error naming the file and key is the reader's
// documented answer to a bad atlas. An atlas it accepts must give the model a finite exterior
// stiffness, or a named status: a non-finite K_ext would reach the haptic force, so it is a
// finding, as is another exception, a sanitizer report or a hang.
#include "touchstone/realtime/mfs/organ_atlas.hpp"

#include "fuzz_input_file.hpp"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <stdexcept>

namespace {

namespace mfs = touchstone::realtime::mfs;

void look_up(const mfs::OrganAtlas& atlas, const mfs::OrganAtlasSample& sample, const Eigen::Vector3d& point_m) {
  mfs::OrganAtlasQuery query;
  query.contact_point_m = point_m;
  query.direction = sample.direction;
  query.tool_radius_m = sample.tool_radius_m;
  query.local_radius_m = sample.local_radius_m;
  query.material.youngs_modulus_Pa = 10e3;
  query.material.poisson_ratio = sample.poisson_ratio;
  const mfs::OrganAtlasLookup lookup = mfs::lookup_exterior_stiffness(atlas, query);
  if (lookup.status != mfs::OrganAtlasStatus::ok) {
    if (lookup.message.empty()) {
      std::fprintf(stderr, "lookup status %s without a message\n", mfs::to_string(lookup.status).c_str());
      std::abort();
    }
    return;
  }
  if (lookup.stiffness_N_per_m.allFinite() && std::isfinite(lookup.relative_error)) return;
  std::fprintf(stderr, "an accepted atlas gave a non-finite K_ext or error estimate at (%g, %g, %g)\n", point_m.x(),
               point_m.y(), point_m.z());
  std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = touchstone::fuzz::write_input_file("atlas.json", data, size);
  try {
    const mfs::OrganAtlas atlas = mfs::read_organ_atlas(path);
    for (const mfs::OrganAtlasSample& sample : atlas.samples) look_up(atlas, sample, sample.contact_point_m);
    if (atlas.samples.size() >= 2)
      look_up(atlas, atlas.samples[0], 0.5 * (atlas.samples[0].contact_point_m + atlas.samples[1].contact_point_m));
  } catch (const std::runtime_error&) {
  }
  return 0;
}
