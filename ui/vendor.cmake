# Copies the 3D view's browser libraries (three.js, urdf-loader) from ui/vendor/node_modules, where
# `npm ci --prefix ui/vendor` installs them from package-lock.json, to DEST, whence mrroc-ui serves
# them as /vendor/<path> (ApiSettings::vendor_dir). Run by the build (cmake -P); fails naming the
# command when they are not installed.
set(files
  three/LICENSE
  three/package.json
  three/build/three.module.js
  three/build/three.core.js
  three/examples/jsm/controls/OrbitControls.js
  three/examples/jsm/loaders/STLLoader.js
  three/examples/jsm/loaders/ColladaLoader.js
  three/examples/jsm/loaders/TGALoader.js
  three/examples/jsm/loaders/collada/ColladaParser.js
  three/examples/jsm/loaders/collada/ColladaComposer.js
  urdf-loader/package.json
  urdf-loader/README.md
  urdf-loader/src/URDFLoader.js
  urdf-loader/src/URDFClasses.js)
set(missing "")
foreach(f ${files})
  if(NOT EXISTS ${SOURCE}/node_modules/${f})
    list(APPEND missing ${f})
  endif()
endforeach()
if(missing)
  list(LENGTH missing n_missing)
  list(LENGTH files n_files)
  if(n_missing EQUAL n_files)
    set(missing_text "all of them (none is installed)")
  else()
    list(JOIN missing ", " missing_text)
  endif()
  message(FATAL_ERROR "The web console's 3D view needs three.js and urdf-loader from the npm "
    "registry, and ${SOURCE}/node_modules lacks ${missing_text}. Install them with\n"
    "  npm ci --prefix ${SOURCE}\n"
    "(versions pinned by ${SOURCE}/package-lock.json) and build again.")
endif()
foreach(f ${files})
  get_filename_component(dir ${DEST}/${f} DIRECTORY)
  file(MAKE_DIRECTORY ${dir})
  file(COPY_FILE ${SOURCE}/node_modules/${f} ${DEST}/${f} ONLY_IF_DIFFERENT)
endforeach()
file(TOUCH ${STAMP})
