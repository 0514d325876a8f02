"""Built-in skill plugin 'cut': cut one dough piece in two with the knife."""
