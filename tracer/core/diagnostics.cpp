// The did-you-mean helper of input messages: the candidate closest to a misspelt word.
#include "core/diagnostics.h"

#include <algorithm>
#include <cctype>
#include <sstream>

namespace tracer {

namespace {

// Optimal-string-alignment distance: Levenshtein plus adjacent transpositions, the commonest
// typing slip ("abledo"). Case-insensitive because "Albedo" is as likely a typo as "albdo".
size_t edit_distance(const std::string& a, const std::string& b) {
  const size_t n = a.size(), m = b.size();
  std::vector<std::vector<size_t>> d(n + 1, std::vector<size_t>(m + 1));
  for (size_t i = 0; i <= n; ++i) d[i][0] = i;
  for (size_t j = 0; j <= m; ++j) d[0][j] = j;
  auto lower = [](char c) { return char(std::tolower(static_cast<unsigned char>(c))); };
  for (size_t i = 1; i <= n; ++i) {
    for (size_t j = 1; j <= m; ++j) {
      const size_t cost = lower(a[i - 1]) == lower(b[j - 1]) ? 0 : 1;
      d[i][j] = std::min({d[i - 1][j] + 1, d[i][j - 1] + 1, d[i - 1][j - 1] + cost});
      if (i > 1 && j > 1 && lower(a[i - 1]) == lower(b[j - 2]) &&
          lower(a[i - 2]) == lower(b[j - 1]))
        d[i][j] = std::min(d[i][j], d[i - 2][j - 2] + 1);
    }
  }
  return d[n][m];
}

}  // namespace

std::string did_you_mean(const std::string& word, const std::vector<std::string>& candidates) {
  // Allow about one slip per three letters, at least one and at most three, so that short words
  // do not match everything.
  const size_t limit = std::clamp<size_t>(word.size() / 3, 1, 3);
  std::string best;
  size_t best_d = limit + 1;
  for (const std::string& c : candidates) {
    const size_t d = edit_distance(word, c);
    if (d < best_d) {
      best_d = d;
      best = c;
    }
  }
  return best;
}

std::string vec3_str(vec3 v, int digits) {
  std::ostringstream ss;
  ss.precision(digits);
  ss << "[" << v.x << ", " << v.y << ", " << v.z << "]";
  return ss.str();
}

}  // namespace tracer
