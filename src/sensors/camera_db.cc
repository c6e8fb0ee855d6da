// SPDX-License-Identifier: MIT
#include "sensors/camera_db.h"

#include <lensfun/lensfun.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <vector>

namespace horizonreg {

namespace {

// Where Debian (and a local install) keep lensfun's XML files.
constexpr const char* kDatabaseDirs[] = {"/usr/share/lensfun/version_1", "/usr/local/share/lensfun/version_1"};

std::string Lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
  return s;
}

// The maker's first word, lower case: "NIKON CORPORATION" -> "nikon",
// "Canon" -> "canon"; its files are named slr-canon.xml, compact-canon.xml ...
std::string MakerKey(const std::string& make) {
  std::string key;
  for (char c : make) {
    if (std::isalnum(static_cast<unsigned char>(c)))
      key += static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    else if (!key.empty())
      break;
  }
  return key;
}

class CameraDatabase {
 public:
  std::optional<double> CropFactor(const std::string& make, const std::string& model) {
    const std::string key = MakerKey(make);
    if (key.empty() || model.empty()) return std::nullopt;
    std::lock_guard<std::mutex> lock(mutex_);
    const std::string cache_key = Lower(make) + '\n' + Lower(model);
    if (auto it = cache_.find(cache_key); it != cache_.end()) return it->second;
    if (!db_) db_.reset(new lfDatabase());
    if (!all_loaded_ && loaded_makers_.insert(key).second) LoadFiles(key);
    std::optional<double> crop = Find(make, model);
    if (!crop && !all_loaded_) {
      all_loaded_ = true;
      // Every file: a maker whose files bear another name. File by file, as
      // lensfun's own lfDatabase::Load() leaks a path string on each call.
      LoadFiles("");
      crop = Find(make, model);
    }
    cache_[cache_key] = crop;
    return crop;
  }

 private:
  // The XML files whose names contain `key` (all of them for ""), each once.
  void LoadFiles(const std::string& key) {
    for (const char* dir : kDatabaseDirs) {
      std::error_code ec;
      for (const auto& entry : std::filesystem::directory_iterator(dir, ec)) {
        const std::string name = entry.path().filename().string();
        if (entry.path().extension() == ".xml" && name.find(key) != std::string::npos &&
            loaded_files_.insert(name).second)
          db_->Load(entry.path().string().c_str());
      }
    }
  }

  std::optional<double> Find(const std::string& make, const std::string& model) const {
    const lfCamera** found = db_->FindCameras(make.c_str(), model.c_str());
    if (!found) return std::nullopt;
    std::optional<double> crop;
    if (found[0] && std::isfinite(found[0]->CropFactor) && found[0]->CropFactor > 0.1f &&
        found[0]->CropFactor < 20.0f)
      crop = found[0]->CropFactor;
    lf_free(found);
    return crop;
  }

  std::mutex mutex_;
  std::unique_ptr<lfDatabase> db_;
  std::set<std::string> loaded_makers_;
  std::set<std::string> loaded_files_;
  bool all_loaded_ = false;
  std::map<std::string, std::optional<double>> cache_;
};

}  // namespace

std::optional<double> CameraCropFactor(const std::string& make, const std::string& model) {
  static CameraDatabase db;
  try {
    return db.CropFactor(make, model);
  } catch (const std::exception&) {
    return std::nullopt;
  }
}

}  // namespace horizonreg
