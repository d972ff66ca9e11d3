#include "vibro/io/run_request.hpp"

#include "vibro/io/result_file.hpp"

namespace vibro::io {

ResultFile open_result_file(const RunRequest& request, const Scene& scene, const RunMeta& meta) {
  return request.in_memory ? ResultFile::create_in_memory(scene, meta)
                           : ResultFile::create(request.output, scene, meta, request.force);
}

}  // namespace vibro::io
