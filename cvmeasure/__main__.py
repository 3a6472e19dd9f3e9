from cvmeasure.cli import console_main

console_main()
