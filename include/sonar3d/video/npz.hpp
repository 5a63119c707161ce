#pragma once
// NumPy's .npy and .npz files, read by hand (no Python at run time), for camera files such as
// IDR/NeuS `cameras_*.npz`. Supported: .npy format versions 1.0–3.0, dtypes float64 and float32
// (little-endian '<f8' '<f4', or '|'-less equivalents), C order; .npz is a zip whose entries are
// stored or deflated (zlib), without encryption or zip64. Hostile input: sizes are checked against
// the file before anything is allocated (an entry cannot inflate beyond what its header declares,
// and a declared size is capped at 64 MiB per entry); every error names the file and the entry.
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

namespace sonar3d {

struct NpyArray {
  std::vector<std::size_t> shape;  // C order
  std::vector<double> data;        // converted to double
};

// Parses one .npy file's bytes; `where` names it in errors ("cameras.npz: world_mat_0.npy").
NpyArray parse_npy(const std::uint8_t* bytes, std::size_t size, const std::string& where);
NpyArray read_npy(const std::filesystem::path& path);

// All arrays of a .npz, by name without the `.npy` suffix. Parses from memory (the fuzz target's
// entry point) or from a file (at most 1 GiB).
std::map<std::string, NpyArray> parse_npz(const std::uint8_t* bytes, std::size_t size,
                                          const std::string& where);
std::map<std::string, NpyArray> read_npz(const std::filesystem::path& path);

}  // namespace sonar3d
