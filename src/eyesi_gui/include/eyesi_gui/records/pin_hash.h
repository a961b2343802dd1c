// PIN hashing for the records store: salted PBKDF2-HMAC-SHA256 (RFC 8018 §5.2), so a copied database file does not
// reveal the PINs (a 4-6 digit PIN is still brute-forceable offline; the iteration count only makes that slower).
#pragma once

#include <string>
#include <vector>

namespace eyesi_gui::records {

struct PinHash {
  std::vector<unsigned char> salt;  // kPinSaltBytes random bytes
  std::vector<unsigned char> hash;  // kPinHashBytes
  int iterations = 0;
};

constexpr int kPinSaltBytes = 16;
constexpr int kPinHashBytes = 32;
constexpr int kPinIterations = 100000;

// A fresh random salt (RAND_bytes) and the PBKDF2 hash of `pin`. Throws StoreError if OpenSSL fails.
PinHash hashPin(const std::string& pin, int iterations = kPinIterations);
// Recomputes the hash with the stored salt and iterations and compares in constant time (CRYPTO_memcmp).
bool verifyPin(const std::string& pin, const PinHash& stored);

}  // namespace eyesi_gui::records
