// Turns the page's inline ES modules (script elements of type text/x-facecap-module) into blob
// URLs and declares them in an import map, so the app's `import 'three'` resolves with no
// network and from file://. Runs as a classic script, before the app's module script is parsed.
( () => {

	const imports = {};
	for ( const element of document.querySelectorAll( 'script[type="text/x-facecap-module"]' ) ) {

		const blob = new Blob( [ element.textContent ], { type: 'text/javascript' } );
		imports[ element.dataset.specifier ] = URL.createObjectURL( blob );

	}

	const map = document.createElement( 'script' );
	map.type = 'importmap';
	map.textContent = JSON.stringify( { imports } );
	document.currentScript.after( map );

} )();
