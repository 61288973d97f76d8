// The corpus test (ctest label `corpus`): every OBJ, glTF and GLB file that Debian's
// assimp-testmodels and glmark2-data install is rendered headless (tiny, few samples, with a time
// limit per file). Each must either render a non-black image with exit 0 or fail with exit 1 and
// an error that names the file; a crash, a hang or a silent black image fails the test. The
// counts per class are printed (docs/TESTING.md records them).
#include <dirent.h>
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <map>
#include <mutex>
#include <thread>

#include "image/image.h"
#include "test_util.h"

namespace {

const char* kFolders[] = {"/usr/share/assimp/models", "/usr/share/glmark2/models"};

bool is_mesh_file(const std::string& name) {
  std::string lower = name;
  std::transform(lower.begin(), lower.end(), lower.begin(),
                 [](unsigned char c) { return char(std::tolower(c)); });
  for (const char* ext : {".obj", ".gltf", ".glb"}) {
    const size_t n = std::char_traits<char>::length(ext);
    if (lower.size() > n && lower.compare(lower.size() - n, n, ext) == 0) return true;
  }
  return false;
}

void find_mesh_files(const std::string& dir, std::vector<std::string>* out) {
  DIR* d = opendir(dir.c_str());
  if (!d) return;
  while (dirent* e = readdir(d)) {
    const std::string name = e->d_name;
    if (name == "." || name == "..") continue;
    const std::string path = dir + "/" + name;
    struct stat st;
    if (stat(path.c_str(), &st) != 0) continue;
    if (S_ISDIR(st.st_mode))
      find_mesh_files(path, out);
    else if (S_ISREG(st.st_mode) && is_mesh_file(name))
      out->push_back(path);
  }
  closedir(d);
}

std::string quoted(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

struct Outcome {
  std::string file, cls, detail;
};

Outcome run_one(const std::string& file, const std::string& out) {
  std::string log;
  // `timeout` reports a hang as 124; a signal shows as 128 + its number.
  const std::string cmd = "timeout -k 5 60 " + test::pathtracer_exe() +
                          " render -q --backend cpu --threads 1 --width 32 --height 32 --spp 4 " +
                          "--out " + quoted(out) + " " + quoted(file);
  const int rc = test::run_command(cmd, &log);
  if (rc == 124 || rc == 137) return {file, "hang", log};
  if (rc >= 128 || rc < 0) return {file, "crash", "exit " + std::to_string(rc) + ": " + log};
  if (rc == 0) {
    const tracer::ImageRGB img = tracer::read_image(out);
    float peak = 0.0f;
    for (float v : img.pixels) peak = std::max(peak, v);
    unlink(out.c_str());
    unlink((out + ".json").c_str());
    if (!(peak > 0.0f)) return {file, "black", log};
    return {file, "rendered", ""};
  }
  // A clear error: exit 1 and an "error:" line that names the file.
  const size_t slash = file.find_last_of('/');
  const std::string base = file.substr(slash + 1);
  const size_t err = log.find("error: ");
  if (rc == 1 && err != std::string::npos && log.find(base, err) != std::string::npos)
    return {file, "error", log.substr(err, log.find('\n', err) - err)};
  return {file, "unclear", "exit " + std::to_string(rc) + ": " + log};
}

TEST(Corpus, EveryPackagedMeshFileRendersOrFailsClearly) {
  std::vector<std::string> files;
  for (const char* f : kFolders) find_mesh_files(f, &files);
  if (files.empty())
    GTEST_SKIP() << "neither assimp-testmodels nor glmark2-data is installed "
                    "(scripts/setup.sh installs them)";
  std::sort(files.begin(), files.end());
  char tmpl[] = "/tmp/pathtracer_corpus_XXXXXX";
  const std::string dir = mkdtemp(tmpl);

  std::vector<Outcome> outcomes(files.size());
  std::atomic<size_t> next{0};
  std::vector<std::thread> workers;
  const unsigned n = std::max(1u, std::min(4u, std::thread::hardware_concurrency()));
  for (unsigned w = 0; w < n; ++w) {
    workers.emplace_back([&, w] {
      for (size_t i; (i = next++) < files.size();)
        outcomes[i] = run_one(files[i], dir + "/" + std::to_string(w) + ".png");
    });
  }
  for (std::thread& t : workers) t.join();
  rmdir(dir.c_str());

  std::map<std::string, int> counts;
  for (const Outcome& o : outcomes) {
    ++counts[o.cls];
    if (o.cls == "error") std::printf("  error    %s\n           %s\n", o.file.c_str(), o.detail.c_str());
    if (o.cls != "rendered" && o.cls != "error")
      ADD_FAILURE() << o.cls << ": " << o.file << "\n" << o.detail;
  }
  std::printf("corpus: %zu files: %d rendered, %d clear errors, %d black, %d unclear, %d crashes, "
              "%d hangs\n",
              files.size(), counts["rendered"], counts["error"], counts["black"],
              counts["unclear"], counts["crash"], counts["hang"]);
}

}  // namespace
