# Hardens the C++ decoders that lcm-gen writes (run on every generated header in DIR right after
# lcm-gen; see docs/fuzzing.md, "Findings").
#
# lcm-gen's decoders trust the lengths they read. A variable-length array is resized to its length
# field before the bytes are checked: a negative length throws std::length_error out of decode();
# a large one allocates gigabytes, and for arrays of doubles the byte count 8 * n then wraps in an
# int, so the decoder reads past the buffer. A string of length < 1 throws std::length_error. Here
# each is rejected as a decode failure (-1) before anything is allocated: an array needs at least
# one byte per element (5 per string: length and NUL; 1 per nested struct) in what is left of the buffer, a string at
# least its NUL. The script fails the build when lcm-gen's output does not have the expected form.
file(GLOB headers "${DIR}/*.hpp")
foreach(header ${headers})
  file(READ "${header}" text)
  if(text MATCHES "mrroc: lengths checked")
    continue()
  endif()
  string(REGEX MATCHALL "\\.resize\\(" resizes "${text}")
  string(REGEX MATCHALL "_len__ > maxlen - pos\\)|__elem_len > maxlen - pos\\)" strings "${text}")
  list(LENGTH resizes n_resizes)
  list(LENGTH strings n_strings)
  # Arrays of numbers: "if(this->n) { this->v.resize(this->n); ...".
  string(REGEX REPLACE
    "    if\\(this->([A-Za-z0-9_]+)\\) {\n        this->([A-Za-z0-9_]+)\\.resize\\(this->[A-Za-z0-9_]+\\);\n"
    "    if(this->\\1 < 0 || this->\\1 > (maxlen - pos) / static_cast<int>(sizeof(this->\\2[0]))) return -1; // mrroc: checked\n    if(this->\\1) {\n        this->\\2.resize(this->\\1);\n"
    text "${text}")
  # Arrays of strings: "this->v.resize(this->n); for (...) { int32_t __elem_len; ...".
  string(REGEX REPLACE
    "    this->([A-Za-z0-9_]+)\\.resize\\(this->([A-Za-z0-9_]+)\\);\n    for \\(int a0 = 0; a0 < this->[A-Za-z0-9_]+; a0\\+\\+\\) {\n        int32_t __elem_len;"
    "    if(this->\\2 < 0 || this->\\2 > (maxlen - pos) / 5) return -1; // mrroc: checked\n    this->\\1.resize(this->\\2);\n    for (int a0 = 0; a0 < this->\\2; a0++) {\n        int32_t __elem_len;"
    text "${text}")
  # Arrays of structs: "this->v.resize(this->n); for (...) { tlen = this->v[a0]._decodeNoHash(...".
  # Every element takes at least one byte.
  string(REGEX REPLACE
    "    this->([A-Za-z0-9_]+)\\.resize\\(this->([A-Za-z0-9_]+)\\);\n    for \\(int a0 = 0; a0 < this->[A-Za-z0-9_]+; a0\\+\\+\\) {\n        tlen = this->[A-Za-z0-9_]+\\[a0\\]\\._decodeNoHash"
    "    if(this->\\2 < 0 || this->\\2 > maxlen - pos) return -1; // mrroc: checked\n    this->\\1.resize(this->\\2);\n    for (int a0 = 0; a0 < this->\\2; a0++) {\n        tlen = this->\\1[a0]._decodeNoHash"
    text "${text}")
  string(REGEX REPLACE "if\\(__([A-Za-z0-9_]+)_len__ > maxlen - pos\\) return -1;"
    "if(__\\1_len__ < 1 || __\\1_len__ > maxlen - pos) return -1;" text "${text}")
  string(REGEX REPLACE "if\\(__elem_len > maxlen - pos\\) return -1;"
    "if(__elem_len < 1 || __elem_len > maxlen - pos) return -1;" text "${text}")
  string(REGEX MATCHALL "// mrroc: checked" checked_arrays "${text}")
  string(REGEX MATCHALL "_len < 1 \\|\\||_len__ < 1 \\|\\|" checked_strings "${text}")
  list(LENGTH checked_arrays n_checked_arrays)
  list(LENGTH checked_strings n_checked_strings)
  if(NOT n_checked_arrays EQUAL n_resizes OR NOT n_checked_strings EQUAL n_strings)
    message(FATAL_ERROR "${header}: lcm-gen wrote decoders of another form than "
      "cmake/harden_lcm_decode.cmake expects (${n_checked_arrays} of ${n_resizes} arrays, "
      "${n_checked_strings} of ${n_strings} strings checked); update the script")
  endif()
  file(WRITE "${header}" "// mrroc: lengths checked by cmake/harden_lcm_decode.cmake\n${text}")
endforeach()
